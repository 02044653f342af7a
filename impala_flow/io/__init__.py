"""MCAP recording and replay of timestamped streams (the engine side: knows no plugin).

- :class:`CodecRegistry`: codecs by Python type and by (schema name, version); one generic
  exact codec (:class:`MessageCodec`) serves every ``@message`` dataclass.
- :class:`MissionWriter`: chunked, indexed MCAP with metadata and Foxglove mirrors.
- :class:`MissionReader`: any valid MCAP file; seek by time, stream chunk by chunk, recover
  cut or damaged files, count what a damaged chunk held (:class:`Loss`).
"""

from ._codec import MESSAGE_ENCODING, SCHEMA_ENCODING, BuiltinCodec, Codec, MessageCodec
from ._errors import (
    BadMagicError,
    CodecError,
    CorruptChunkError,
    CorruptSummaryError,
    EmptyFileError,
    NotMcapError,
    RecordingError,
    SchemaConflictError,
    SchemaMismatchError,
    TruncatedRecordingError,
    UnknownSchemaError,
)
from ._foxglove import foxglove_topic
from ._jsonview import encode as encode_json
from ._jsonview import json_schema, to_json
from ._reader import ChannelInfo, Loss, MissionReader, Recorded, RecordingInfo
from ._registry import CodecRegistry
from ._writer import COMPRESSIONS, MissionWriter

__all__ = [
    "CodecRegistry", "Codec", "MessageCodec", "BuiltinCodec", "SCHEMA_ENCODING",
    "MESSAGE_ENCODING", "MissionWriter", "COMPRESSIONS", "MissionReader", "RecordingInfo",
    "ChannelInfo", "Recorded", "Loss", "foxglove_topic", "to_json", "json_schema", "encode_json",
    "CodecError", "SchemaConflictError", "UnknownSchemaError", "SchemaMismatchError",
    "RecordingError", "EmptyFileError", "NotMcapError", "BadMagicError",
    "TruncatedRecordingError", "CorruptChunkError", "CorruptSummaryError",
]
