"""MCAP recording and replay of timestamped streams (the engine side: knows no plugin).

- :class:`CodecRegistry`: codecs by Python type and by (schema name, version); one generic
  exact codec (:class:`MessageCodec`) serves every ``@message`` dataclass.
- :class:`MissionWriter`: chunked, indexed MCAP with metadata and Foxglove mirrors.
- :class:`MissionReader`: any valid MCAP file; seek by time, stream chunk by chunk, recover
  cut or damaged files, count what a damaged chunk held (:class:`Loss`).
"""

from .codec import MESSAGE_ENCODING, SCHEMA_ENCODING, BuiltinCodec, Codec, MessageCodec
from .errors import (
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
from .foxglove import foxglove_topic
from .reader import ChannelInfo, Loss, MissionReader, Recorded, RecordingInfo
from .registry import CodecRegistry
from .writer import COMPRESSIONS, MissionWriter

__all__ = [
    "CodecRegistry", "Codec", "MessageCodec", "BuiltinCodec", "SCHEMA_ENCODING",
    "MESSAGE_ENCODING", "MissionWriter", "COMPRESSIONS", "MissionReader", "RecordingInfo",
    "ChannelInfo", "Recorded", "Loss", "foxglove_topic",
    "CodecError", "SchemaConflictError", "UnknownSchemaError", "SchemaMismatchError",
    "RecordingError", "EmptyFileError", "NotMcapError", "BadMagicError",
    "TruncatedRecordingError", "CorruptChunkError", "CorruptSummaryError",
]
