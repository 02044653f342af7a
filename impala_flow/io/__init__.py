"""MCAP recording and replay of timestamped streams (the engine side: knows no plugin).

- :class:`CodecRegistry`: codecs by Python type and by (schema name, version); one generic
  exact codec (:class:`MessageCodec`) serves every ``@message`` dataclass.
- :class:`MissionWriter`: chunked, indexed MCAP with metadata and the mirrors plugins register
  (:class:`Mirror`: e.g. the view plugin's Foxglove schemas) and the foreign formats they register
  (:class:`ForeignWriter`: e.g. the ros2 plugin's ROS 2 messages).
- :class:`MissionReader`: any valid MCAP file; seek by time, stream chunk by chunk, recover
  cut or damaged files, count what a damaged chunk held (:class:`Loss`).
- Channel adapters (:class:`ChannelAdapter`): plugins read foreign channels (a rosbag2's ROS 2
  messages) as the project's samples; the reader, ``info``, ``export`` and the Replayer use them.
- The engine's own components, YAML types ``io.Recorder`` (:class:`Recorder`) and ``io.Replayer``
  (:class:`Replayer`): record streams of a graph, replay a recording as a source.
"""

from ._adapter import ANY_SCHEMA, AdaptedChannel, AdapterContext, ChannelAdapter
from ._bag import BagReader, open_recording
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
from ._foreign import ForeignChannel, ForeignWriter
from ._jsonview import encode as encode_json
from ._jsonview import json_schema, to_json
from ._mirror import MIRROR_KEY, TRANSFORMS, Mirror
from ._reader import ChannelInfo, Loss, MissionReader, Recorded, RecordingInfo
from ._recorder import VEHICLE_POSES, Recorder
from ._registry import CodecRegistry
from ._replayer import TIME_JUMP, Replayer
from ._runcodecs import run_codecs, set_plugin_loader
from ._writer import COMPRESSIONS, MissionWriter

__all__ = [
    "CodecRegistry", "Codec", "MessageCodec", "BuiltinCodec", "SCHEMA_ENCODING",
    "MESSAGE_ENCODING", "MissionWriter", "COMPRESSIONS", "MissionReader", "RecordingInfo",
    "ChannelInfo", "Recorded", "Loss", "Mirror", "MIRROR_KEY", "TRANSFORMS", "to_json", "json_schema", "encode_json",
    "CodecError", "SchemaConflictError", "UnknownSchemaError", "SchemaMismatchError",
    "ForeignChannel", "ForeignWriter", "RecordingError", "EmptyFileError", "NotMcapError", "BadMagicError",
    "TruncatedRecordingError", "CorruptChunkError", "CorruptSummaryError",
    "ChannelAdapter", "AdaptedChannel", "AdapterContext", "ANY_SCHEMA", "BagReader", "open_recording",
    "Recorder", "Replayer", "TIME_JUMP", "VEHICLE_POSES", "run_codecs", "set_plugin_loader",
]
