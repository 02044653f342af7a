"""Low-level MCAP access for the reader: footer/summary, forward recovery scan, chunks.

Built on :mod:`mcap.records` for the record layouts; chunks are parsed here with
``struct.unpack_from`` over one buffer so message payloads are zero-copy memoryviews,
every chunk is CRC-checked, and a damaged or cut file is described instead of crashing.
"""

from __future__ import annotations

import io
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import BinaryIO

import lz4.frame
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, ChunkIndex, Header, Metadata, Schema, Statistics

from .errors import (
    BadMagicError,
    CorruptChunkError,
    CorruptSummaryError,
    EmptyFileError,
    NotMcapError,
    RecordingError,
    TruncatedRecordingError,
)

MAGIC = b"\x89MCAP0\r\n"
_REC = struct.Struct("<BQ")
_FOOTER = struct.Struct("<BQQQI")  # opcode, length (=20), summary_start, offset_start, crc
_CHUNK_HEAD = struct.Struct("<QQQI")  # start, end, uncompressed size, uncompressed crc
_MSG = struct.Struct("<HIQQ")  # channel, sequence, log_time, publish_time
_U32, _U64 = struct.Struct("<I"), struct.Struct("<Q")
TAIL_SIZE = _FOOTER.size + len(MAGIC)


@dataclass
class ChunkRef:
    """Where one chunk is and what it holds (from the index, or from the recovery scan)."""

    offset: int
    length: int  # whole record, opcode and length prefix included
    start_ns: int
    end_ns: int
    compression: str
    channel_ids: frozenset[int] | None = None  # None: unknown without reading the chunk


@dataclass
class FileMap:
    """Everything known about a file before reading its messages."""

    size: int
    header: Header | None = None
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    chunks: list[ChunkRef] = field(default_factory=list)
    counts: dict[int, int] = field(default_factory=dict)
    start_ns: int | None = None  # None: no message
    end_ns: int | None = None
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    truncated: bool = False
    indexed: bool = False
    problems: list[RecordingError] = field(default_factory=list)
    corrupt_offsets: set[int] = field(default_factory=set)
    loose_messages: int = 0


def check_magic(path: str, f: BinaryIO, size: int) -> None:
    """Raise the RecordingError that says why ``f`` is not a readable MCAP at all."""
    if size == 0:
        raise EmptyFileError(path)
    f.seek(0)
    head = f.read(len(MAGIC))
    if head == MAGIC:
        return
    if MAGIC.startswith(head):
        raise TruncatedRecordingError(path, f"truncated recording: only {size} bytes, "
                                            "cut inside the MCAP magic")
    if head[:5] == MAGIC[:5]:
        raise BadMagicError(path, f"wrong MCAP magic {head!r} (expected {MAGIC!r}: "
                                  "unsupported MCAP version or damaged header)")
    raise NotMcapError(path, f"not an MCAP file (starts with {head[:8]!r})")


def read_indexed(path: str, f: BinaryIO, size: int) -> FileMap | None:
    """Map a complete file through its footer and summary; None if the footer is missing."""
    if size < len(MAGIC) * 2 + _FOOTER.size:
        return None
    f.seek(size - TAIL_SIZE)
    tail = f.read(TAIL_SIZE)
    if tail[-8:] != MAGIC:
        return None
    op, length, s_start, so_start, crc = _FOOTER.unpack_from(tail)
    if op != Opcode.FOOTER or length != 20 or s_start >= size:
        return None
    fm = FileMap(size=size, indexed=True)
    if s_start == 0:
        return None  # valid file without summary: the forward scan maps it
    footer_at = size - TAIL_SIZE
    f.seek(s_start)
    summary = f.read(footer_at - s_start)
    if crc != 0 and zlib.crc32(tail[:_FOOTER.size - 4], zlib.crc32(summary)) != crc:
        raise CorruptSummaryError(path, "corrupt summary section (CRC mismatch)")
    stream = ReadDataStream(io.BytesIO(summary))
    metadata_at: list[int] = []
    try:
        while stream.count < len(summary):
            op = stream.read1()
            length = stream.read8()
            end = stream.count + length
            if op == Opcode.SCHEMA:
                s = Schema.read(stream)
                fm.schemas[s.id] = s
            elif op == Opcode.CHANNEL:
                c = Channel.read(stream)
                fm.channels[c.id] = c
            elif op == Opcode.STATISTICS:
                st = Statistics.read(stream)
                fm.counts = dict(st.channel_message_counts)
                fm.start_ns, fm.end_ns = st.message_start_time, st.message_end_time
            elif op == Opcode.CHUNK_INDEX:
                ci = ChunkIndex.read(stream)
                fm.chunks.append(ChunkRef(
                    ci.chunk_start_offset, ci.chunk_length, ci.message_start_time,
                    ci.message_end_time, ci.compression,
                    frozenset(ci.message_index_offsets) or None))
            elif op == Opcode.METADATA_INDEX:
                metadata_at.append(stream.read8())
            if stream.count < end:
                stream.read(end - stream.count)
    except (McapError, struct.error, UnicodeDecodeError) as e:
        raise CorruptSummaryError(path, f"corrupt summary section ({e})") from None
    f.seek(0)
    fm.header = _read_header(f)
    for off in metadata_at:
        f.seek(off)
        rec = f.read(_REC.size)
        _, length = _REC.unpack(rec)
        m = Metadata.read(ReadDataStream(io.BytesIO(f.read(length))))
        fm.metadata[m.name] = dict(m.metadata)
    return fm


def _read_header(f: BinaryIO) -> Header | None:
    f.seek(len(MAGIC))
    rec = f.read(_REC.size)
    if len(rec) < _REC.size:
        return None
    op, length = _REC.unpack(rec)
    if op != Opcode.HEADER:
        return None
    return Header.read(ReadDataStream(io.BytesIO(f.read(length))))


def scan(path: str, f: BinaryIO, size: int, truncated: bool) -> FileMap:
    """Forward scan from the start, up to the last complete record: the recovery path.

    Every chunk is read, decompressed and CRC-checked (one at a time: bounded memory); a
    corrupt chunk is skipped and listed in ``problems``.
    """
    fm = FileMap(size=size, truncated=truncated)
    pos = len(MAGIC)
    saw_end = False
    while True:
        f.seek(pos)
        head = f.read(_REC.size)
        if len(head) < _REC.size:
            break
        op, length = _REC.unpack(head)
        body_at = pos + _REC.size
        if body_at + length > size:
            fm.truncated = True
            break
        if op == Opcode.CHUNK:
            f.seek(pos)
            _scan_chunk(path, fm, pos, f.read(_REC.size + length))
        elif op in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.METADATA, Opcode.HEADER):
            _note(fm, op, f.read(length))
        elif op == Opcode.MESSAGE:
            fm.loose_messages += 1
        elif op in (Opcode.DATA_END, Opcode.FOOTER):
            saw_end = True
            break
        elif op not in (Opcode.MESSAGE_INDEX, Opcode.ATTACHMENT, Opcode.ATTACHMENT_INDEX,
                        Opcode.CHUNK_INDEX, Opcode.METADATA_INDEX, Opcode.STATISTICS,
                        Opcode.SUMMARY_OFFSET) and (op == 0 or op > 0x7F):
            fm.truncated = True  # garbage where a record should start
            break
        pos = body_at + length
    if not saw_end:
        fm.truncated = True
    if fm.loose_messages:
        fm.problems.append(RecordingError(
            path, f"{fm.loose_messages} messages outside chunks were not read "
                  "(unchunked MCAP is not supported)"))
    return fm


def _note(fm: FileMap, op: int, body: bytes) -> None:
    stream = ReadDataStream(io.BytesIO(body))
    if op == Opcode.SCHEMA:
        s = Schema.read(stream)
        fm.schemas[s.id] = s
    elif op == Opcode.CHANNEL:
        c = Channel.read(stream)
        fm.channels[c.id] = c
    elif op == Opcode.METADATA:
        m = Metadata.read(stream)
        fm.metadata[m.name] = dict(m.metadata)
    elif op == Opcode.HEADER:
        fm.header = Header.read(stream)


def _scan_chunk(path: str, fm: FileMap, pos: int, raw: bytes) -> None:
    try:
        ref, records = parse_chunk(path, pos, raw)
    except CorruptChunkError as e:
        fm.problems.append(e)
        fm.corrupt_offsets.add(pos)
        return
    ids: set[int] = set()
    n = 0
    for op, body in iter_records(records):
        if op == Opcode.MESSAGE:
            cid, _, t, _ = _MSG.unpack_from(body)
            ids.add(cid)
            fm.counts[cid] = fm.counts.get(cid, 0) + 1
            if fm.start_ns is None or t < fm.start_ns:
                fm.start_ns = t
            if fm.end_ns is None or t > fm.end_ns:
                fm.end_ns = t
            n += 1
        elif op in (Opcode.SCHEMA, Opcode.CHANNEL):
            _note(fm, op, bytes(body))
    if n:
        ref.channel_ids = frozenset(ids)
        fm.chunks.append(ref)


def parse_chunk(path: str, pos: int, raw: bytes) -> tuple[ChunkRef, memoryview]:
    """Decompress and CRC-check one chunk record (``raw`` = the whole record)."""
    try:
        op, length = _REC.unpack_from(raw)
        if op != Opcode.CHUNK or len(raw) < _REC.size + length:
            raise CorruptChunkError(path, f"chunk at offset {pos}: not a complete chunk record")
        at = _REC.size
        start, end, usize, crc = _CHUNK_HEAD.unpack_from(raw, at)
        at += _CHUNK_HEAD.size
        (clen,) = _U32.unpack_from(raw, at)
        compression = raw[at + 4 : at + 4 + clen].decode("ascii")
        at += 4 + clen
        (dlen,) = _U64.unpack_from(raw, at)
        at += 8
        data = memoryview(raw)[at : at + dlen]
        if compression == "zstd":
            records: bytes | memoryview = zstandard.ZstdDecompressor().decompress(
                data, max_output_size=usize)
        elif compression == "lz4":
            records = lz4.frame.decompress(data)
        elif compression == "":
            records = data
        else:
            raise CorruptChunkError(path, f"chunk at offset {pos}: unknown compression "
                                          f"{compression!r}")
    except (struct.error, UnicodeDecodeError, zstandard.ZstdError, RuntimeError) as e:
        raise CorruptChunkError(path, f"chunk at offset {pos}: cannot decompress ({e})") \
            from None
    if len(records) != usize:
        raise CorruptChunkError(path, f"chunk at offset {pos}: {len(records)} bytes after "
                                      f"decompression, {usize} expected")
    if crc and zlib.crc32(records) != crc:
        raise CorruptChunkError(path, f"chunk at offset {pos}: CRC mismatch (flipped bits?)")
    ref = ChunkRef(pos, _REC.size + length, start, end, compression)
    return ref, memoryview(records)


def iter_records(buf: memoryview) -> Iterator[tuple[int, memoryview]]:
    """(opcode, body) of each record inside a decompressed chunk."""
    pos, n = 0, len(buf)
    unpack = _REC.unpack_from
    while pos < n:
        op, length = unpack(buf, pos)
        body_at = pos + 9
        yield op, buf[body_at : body_at + length]
        pos = body_at + length


def read_chunk(path: str, f: BinaryIO, ref: ChunkRef) -> memoryview:
    """Records of the chunk ``ref`` (CorruptChunkError when damaged)."""
    f.seek(ref.offset)
    raw = f.read(ref.length)
    if len(raw) != ref.length:
        raise CorruptChunkError(path, f"chunk at offset {ref.offset}: file ends inside it")
    return parse_chunk(path, ref.offset, raw)[1]


MSG_HEAD = _MSG
