"""Errors raised by the io layer: codecs, schemas and bad recordings.

Every :class:`RecordingError` renders as one line naming the file and what is wrong, so a
command line can print it as it is, never a traceback.
"""

from __future__ import annotations

import os

__all__ = [
    "CodecError", "SchemaConflictError", "UnknownSchemaError", "SchemaMismatchError",
    "RecordingError", "EmptyFileError", "NotMcapError", "BadMagicError",
    "TruncatedRecordingError", "CorruptChunkError", "CorruptSummaryError",
]


class CodecError(ValueError):
    """A value cannot be encoded (unsupported type or dtype) or a payload cannot be decoded."""


class SchemaConflictError(CodecError):
    """Two plugins registered the same schema name and version (or the same Python type)."""


class UnknownSchemaError(CodecError, LookupError):
    """A channel's schema (name, version, encoding) has no codec in the registry."""

    def __init__(self, topic: str, schema: str, version: int | None, detail: str = "") -> None:
        self.topic, self.schema, self.version = topic, schema, version
        v = "" if version is None else f" version {version}"
        msg = f"channel {topic!r}: no codec for schema {schema!r}{v}"
        super().__init__(msg + (f" ({detail})" if detail else ""))


class SchemaMismatchError(UnknownSchemaError):
    """A channel's stored field layout differs from the registered type of the same version."""


class RecordingError(Exception):
    """A recording that cannot be read (in whole or in part). ``str()`` is one line."""

    what = "bad recording"

    def __init__(self, path: str | os.PathLike[str], reason: str = "") -> None:
        self.path = os.fspath(path)
        self.reason = reason or self.what
        super().__init__(f"{self.path}: {self.reason}")


class EmptyFileError(RecordingError):
    what = "empty file (0 bytes), not an MCAP recording"


class NotMcapError(RecordingError):
    what = "not an MCAP file"


class BadMagicError(RecordingError):
    what = "wrong MCAP magic"


class TruncatedRecordingError(RecordingError):
    what = "truncated recording (no valid footer/summary)"


class CorruptChunkError(RecordingError):
    what = "corrupt chunk"


class CorruptSummaryError(RecordingError):
    what = "corrupt summary section"
