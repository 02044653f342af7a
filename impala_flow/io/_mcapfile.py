"""Low-level MCAP access for the reader: footer/summary, forward scan, chunks, damage.

Built on :mod:`mcap.records` for the record layouts; chunks are parsed here with
``struct.unpack_from`` over one buffer so message payloads are zero-copy memoryviews (the
bench, bench/recording.py, shows this path reads faster than the bare ``mcap`` reader, which
a wrapper around it could not). Every chunk is CRC-checked and every length is bounded by
the file size, so a damaged or cut file is described instead of crashing.

Two ways to map a file:

- :func:`read_indexed` trusts the summary when it is complete: a chunk index, statistics,
  and a data section made only of those chunks (the gaps between them are walked record by
  record, cheaply, to make sure no message or chunk lies outside the index);
- :func:`scan` reads the whole data section otherwise (no summary, no chunk index, no
  statistics, messages outside chunks, a damaged summary or a cut file). Messages outside
  chunks are grouped in runs (:attr:`ChunkRef.loose`) read like uncompressed chunks. A record
  whose length cannot be right is skipped by resynchronising on the next plausible record,
  and the skip is one problem line naming the file and the offsets.
"""

from __future__ import annotations

import io
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import BinaryIO

import lz4.frame
import numpy as np
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, ChunkIndex, Header, Metadata, Schema, Statistics

from ._errors import (
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
_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")
TAIL_SIZE = _FOOTER.size + len(MAGIC)
_DATA_END_SIZE = _REC.size + 4
_MAX_CHUNK = 1 << 32  # uncompressed bytes, the bound of the mcap library's own reader
_LOOSE_RUN = 1 << 20  # bytes of messages outside chunks grouped in one run
_WINDOW = 1 << 20  # bytes read at once by the forward scan
_KNOWN = frozenset(int(op) for op in Opcode)
_NAMES = {int(op): op.name.title().replace("_", "") for op in Opcode}
_DECODE_ERRORS = (McapError, struct.error, UnicodeDecodeError, ValueError, EOFError)


@dataclass
class ChunkRef:
    """Where one chunk (or run of messages outside chunks) is and what it holds."""

    offset: int
    length: int  # whole record(s), opcode and length prefix included
    start_ns: int
    end_ns: int
    compression: str
    channel_ids: frozenset[int] | None = None  # None: unknown without reading the chunk
    index: dict[int, int] = field(default_factory=dict)  # channel -> Message Index offset
    loose: bool = False  # messages outside any chunk, read in place
    index_end: int = 0  # end of the chunk's message indexes (from the chunk index)


@dataclass
class FileMap:
    """Everything known about a file before reading its messages."""

    size: int
    header: Header | None = None
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    chunks: list[ChunkRef] = field(default_factory=list)  # corrupt ones included
    counts: dict[int, int] = field(default_factory=dict)
    start_ns: int | None = None  # None: no message
    end_ns: int | None = None
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: list[tuple[str, str, int, int]] = field(default_factory=list)  # name, media, bytes, at
    truncated: bool = False
    indexed: bool = False
    summary_crc_ok: bool = True
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


def footer_ok(f: BinaryIO, size: int) -> bool:
    """The file ends with a Footer record and the closing magic (it was not cut)."""
    if size < len(MAGIC) * 2 + _FOOTER.size:
        return False
    f.seek(size - TAIL_SIZE)
    tail = f.read(TAIL_SIZE)
    op, length = _REC.unpack_from(tail)
    return tail[-8:] == MAGIC and op == Opcode.FOOTER and length == 20


def _damaged(path: str, at: int, op: int, why: str) -> RecordingError:
    name = _NAMES.get(op, f"opcode 0x{op:02x}")
    return RecordingError(path, f"offset {at}: damaged {name} record ({why}); skipped")


def _read_record(path: str, f: BinaryIO, at: int, size: int, op: int) -> bytes:
    """Body of the record of opcode ``op`` at ``at``, its length bounded by the file size."""
    f.seek(at)
    head = f.read(_REC.size)
    if len(head) < _REC.size:
        raise _damaged(path, at, op, "file ends inside it")
    got, length = _REC.unpack(head)
    if got != op:
        raise _damaged(path, at, op, f"opcode 0x{got:02x} found")
    if length > size - at - _REC.size:
        raise _damaged(path, at, op, f"length {length} beyond the end of the file")
    return f.read(length)


def read_indexed(path: str, f: BinaryIO, size: int) -> FileMap | None:
    """Map a file through its footer and summary; None when the summary cannot map it
    alone (no footer, no summary, no chunk index or statistics, or data outside the index)."""
    if size < len(MAGIC) * 2 + _FOOTER.size:
        return None
    f.seek(size - TAIL_SIZE)
    tail = f.read(TAIL_SIZE)
    if tail[-8:] != MAGIC:
        return None
    op, length, s_start, so_start, crc = _FOOTER.unpack_from(tail)
    footer_at = size - TAIL_SIZE
    if op != Opcode.FOOTER or length != 20 or s_start > footer_at or s_start < len(MAGIC):
        return None  # s_start == 0: valid file without summary, the forward scan maps it
    fm = FileMap(size=size, indexed=True)
    f.seek(s_start)
    summary = f.read(footer_at - s_start)
    if crc != 0 and zlib.crc32(tail[:_FOOTER.size - 4], zlib.crc32(summary)) != crc:
        raise CorruptSummaryError(path, f"offset {s_start}: corrupt summary section (CRC mismatch)")
    stream = ReadDataStream(io.BytesIO(summary))
    metadata_at: list[int] = []
    has_stats = False
    try:
        while stream.count < len(summary):
            op = stream.read1()
            length = stream.read8()
            end = stream.count + length
            if end > len(summary):
                raise ValueError(f"record length {length} beyond the summary")
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
                has_stats = True
                if st.message_count and not st.channel_message_counts:
                    has_stats = False  # total only: per-channel counts come from a scan
            elif op == Opcode.CHUNK_INDEX:
                ci = ChunkIndex.read(stream)
                fm.chunks.append(ChunkRef(
                    ci.chunk_start_offset, ci.chunk_length, ci.message_start_time,
                    ci.message_end_time, ci.compression,
                    frozenset(ci.message_index_offsets) or None, dict(ci.message_index_offsets),
                    index_end=ci.chunk_start_offset + ci.chunk_length + ci.message_index_length))
            elif op == Opcode.METADATA_INDEX:
                metadata_at.append(stream.read8())
            elif op == Opcode.ATTACHMENT_INDEX:
                a_at, a_len = stream.read8(), stream.read8()
                stream.read8()  # log time
                stream.read8()  # create time
                a_size = stream.read8()
                name = stream.read_prefixed_string()
                media = stream.read_prefixed_string()
                fm.attachments.append((name, media, a_size, a_at))
                del a_len
            if stream.count < end:
                stream.read(end - stream.count)
    except (*_DECODE_ERRORS, KeyError) as e:
        raise CorruptSummaryError(path, f"offset {s_start}: corrupt summary section ({e})") from None
    described = {c for c, n in fm.counts.items() if n} <= set(fm.channels) and all(
        c.schema_id == 0 or c.schema_id in fm.schemas for c in fm.channels.values())
    if not has_stats or not described or (not fm.chunks and sum(fm.counts.values())):
        return None  # counts, channels or chunk positions unknown: the forward scan finds them
    for ref in fm.chunks:
        if ref.offset + ref.length > s_start or ref.offset < len(MAGIC):
            raise CorruptSummaryError(path, f"offset {s_start}: chunk index points outside the "
                                            f"data section (offset {ref.offset})")
    walked: set[int] = set()  # metadata records met in the gaps between chunks
    if not _data_section_indexed(path, f, fm, s_start, size, walked):
        return None
    fm.header = _header(path, f, size, fm)
    for off in metadata_at:
        if off in walked:
            continue
        try:
            body = _read_record(path, f, off, size, Opcode.METADATA)
            m = Metadata.read(ReadDataStream(io.BytesIO(body)))
        except RecordingError as e:
            fm.problems.append(e)
            continue
        except _DECODE_ERRORS as e:
            fm.problems.append(_damaged(path, off, Opcode.METADATA, str(e) or type(e).__name__))
            continue
        fm.metadata[m.name] = dict(m.metadata)
    return fm


def _data_section_indexed(path: str, f: BinaryIO, fm: FileMap, s_start: int, size: int,
                          walked: set[int]) -> bool:
    """True when every record of the data section outside the indexed chunks (and their
    message indexes) is neither a message nor a chunk: walks only the gaps, reading 9-byte
    record heads (nothing at all between back-to-back chunks); metadata and attachments met
    there are noted (a summary without their indexes still lists them)."""
    spans = sorted((r.offset, r.index_end) for r in fm.chunks)
    spans.append((s_start, s_start))
    pos = len(MAGIC)
    for begin, end in spans:
        while pos < begin:
            f.seek(pos)
            head = f.read(_REC.size)
            if len(head) < _REC.size:
                return False
            op, length = _REC.unpack(head)
            nxt = pos + _REC.size + length
            if op in (Opcode.MESSAGE, Opcode.CHUNK) or op == 0 or nxt > begin:
                return False
            if op in (Opcode.DATA_END, Opcode.FOOTER):
                return begin == s_start
            if op == Opcode.METADATA:
                walked.add(pos)
                _note(path, fm, pos, op, f.read(length))
            elif op == Opcode.ATTACHMENT and all(a[3] != pos for a in fm.attachments):
                _note_attachment(path, fm, f, pos, length)
            pos = nxt
        if pos != begin:
            return False
        pos = max(pos, end)
    return True


def _header(path: str, f: BinaryIO, size: int, fm: FileMap) -> Header | None:
    try:
        body = _read_record(path, f, len(MAGIC), size, Opcode.HEADER)
        return Header.read(ReadDataStream(io.BytesIO(body)))
    except RecordingError as e:
        fm.problems.append(e)
    except _DECODE_ERRORS as e:
        fm.problems.append(_damaged(path, len(MAGIC), Opcode.HEADER, str(e) or type(e).__name__))
    return None


def scan(path: str, f: BinaryIO, size: int, truncated: bool) -> FileMap:
    """Forward scan of the whole data section: the path of files the summary cannot map.

    Every chunk is read, decompressed and CRC-checked (one at a time: bounded memory); a
    corrupt chunk is listed in ``problems`` and ``corrupt_offsets``, with the message indexes
    that follow it (they say what it held). A record of impossible length (or opcode 0) is
    skipped by resynchronising on the next plausible record.
    """
    fm = FileMap(size=size, truncated=truncated)
    pos = len(MAGIC)
    saw_end = False
    last: ChunkRef | None = None
    run: list[int] = []  # [offset, end, t_min, t_max, channel ids...] of the current loose run
    # record heads and message headers are read through a window of the file (an unchunked
    # file is one small record per message: a read call each would dominate the scan)
    win, win_at = b"", 0
    unpack_rec, unpack_msg = _REC.unpack_from, _MSG.unpack_from
    while True:
        off = pos - win_at
        if off < 0 or off + _REC.size + _MSG.size > len(win):
            f.seek(pos)
            win, win_at, off = f.read(_WINDOW), pos, 0
        if len(win) - off < _REC.size:
            break
        op, length = unpack_rec(win, off)
        body_at = pos + _REC.size
        if op == 0 or length > size:  # impossible even for a longer (uncut) file
            nxt = _resync(path, f, pos + 1, size)
            why = "opcode 0" if op == 0 else f"length {length} beyond the end of the file"
            to = f"to offset {nxt}" if nxt is not None else "to the end of the file"
            fm.problems.append(RecordingError(path, f"offset {pos}: damaged "
                                              f"{_NAMES.get(op, f'opcode 0x{op:02x}')} record ({why}); "
                                              f"skipped {(nxt or size) - pos} bytes {to}"))
            _close_run(fm, run)
            if nxt is None:
                break
            pos = nxt
            continue
        if body_at + length > size:
            fm.truncated = True
            break
        if op != Opcode.MESSAGE and op not in (Opcode.SCHEMA, Opcode.CHANNEL):
            _close_run(fm, run)
        if op == Opcode.CHUNK:
            f.seek(pos)
            last = _scan_chunk(path, fm, pos, f.read(_REC.size + length))
        elif op == Opcode.MESSAGE_INDEX:
            if last is not None and length >= 6:
                f.seek(body_at)
                last.index[_U16.unpack(f.read(2))[0]] = pos
        elif op in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.METADATA, Opcode.HEADER):
            f.seek(body_at)
            _note(path, fm, pos, op, f.read(length))
        elif op == Opcode.MESSAGE:
            if length < _MSG.size:
                fm.problems.append(_damaged(path, pos, op, "shorter than a message header"))
            else:
                cid, _, t, _ = unpack_msg(win, off + _REC.size)
                _loose(fm, run, pos, body_at + length, cid, t)
        elif op == Opcode.ATTACHMENT:
            _note_attachment(path, fm, f, pos, length)
        elif op in (Opcode.DATA_END, Opcode.FOOTER):
            saw_end = True
            break
        pos = body_at + length
    _close_run(fm, run)
    if not saw_end:
        fm.truncated = True
    return fm


def _loose(fm: FileMap, run: list[int], pos: int, end: int, cid: int, t: int) -> None:
    if run and (pos != run[1] or end - run[0] > _LOOSE_RUN):
        _close_run(fm, run)
    if not run:
        run += [pos, end, t, t]
    run[1] = end
    if t < run[2]:
        run[2] = t
    elif t > run[3]:
        run[3] = t
    run.append(cid)
    fm.loose_messages += 1
    counts = fm.counts
    counts[cid] = counts.get(cid, 0) + 1
    if fm.start_ns is None or t < fm.start_ns:
        fm.start_ns = t
    if fm.end_ns is None or t > fm.end_ns:
        fm.end_ns = t


def _close_run(fm: FileMap, run: list[int]) -> None:
    if run:
        fm.chunks.append(ChunkRef(run[0], run[1] - run[0], run[2], run[3], "",
                                  frozenset(run[4:]), loose=True))
        run.clear()


def _resync(path: str, f: BinaryIO, at: int, size: int) -> int | None:
    """Offset of the next plausible record at or after ``at``: a chunk that decompresses and
    passes its CRC, or a record of known opcode whose length fits and is followed by another
    such record (or the end of the file). None if there is none."""
    block = 1 << 20
    while at < size - _REC.size:
        f.seek(at)
        buf = f.read(block + _REC.size)
        arr = np.frombuffer(buf, np.uint8)
        n = len(arr) - _REC.size
        if n <= 0:
            return None
        cand = np.nonzero((arr[:n] >= 1) & (arr[:n] <= 0x0F))[0]
        if len(cand):
            lengths = arr[cand[:, None] + np.arange(1, 9)].copy().view("<u8")[:, 0]
            ok = lengths <= (size - at - cand - _REC.size).astype(np.uint64)
            for i in cand[ok]:
                if _plausible(path, f, at + int(i), size):
                    return at + int(i)
        at += n
    return None


def _plausible(path: str, f: BinaryIO, at: int, size: int) -> bool:
    f.seek(at)
    op, length = _REC.unpack(f.read(_REC.size))
    nxt = at + _REC.size + length
    if op == Opcode.CHUNK:
        f.seek(at)
        try:
            parse_chunk(path, at, f.read(_REC.size + length))
        except CorruptChunkError:
            return False
        return True
    if op not in _KNOWN:
        return False
    if nxt == size or (op == Opcode.FOOTER and nxt == size - len(MAGIC)):
        return True
    f.seek(nxt)
    head = f.read(_REC.size)
    if len(head) < _REC.size:
        return False
    op2, length2 = _REC.unpack(head)
    return op2 in _KNOWN and nxt + _REC.size + length2 <= size


def _note(path: str, fm: FileMap, pos: int, op: int, body: bytes | memoryview) -> None:
    stream = ReadDataStream(io.BytesIO(body))
    try:
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
    except _DECODE_ERRORS as e:
        fm.problems.append(_damaged(path, pos, op, str(e) or type(e).__name__))


def _note_attachment(path: str, fm: FileMap, f: BinaryIO, pos: int, length: int) -> None:
    try:
        f.seek(pos + _REC.size + 16)  # log time, create time
        name = f.read(_U32.unpack(f.read(4))[0]).decode()
        media = f.read(_U32.unpack(f.read(4))[0]).decode()
        (n,) = _U64.unpack(f.read(8))
        fm.attachments.append((name, media, n, pos))
    except (struct.error, UnicodeDecodeError) as e:
        fm.problems.append(_damaged(path, pos, Opcode.ATTACHMENT, str(e)))
    del length


def chunk_times(raw: bytes) -> tuple[int, int]:
    """(start, end) message times written in a chunk record's header (0, 0 if unreadable)."""
    try:
        start, end, _, _ = _CHUNK_HEAD.unpack_from(raw, _REC.size)
    except struct.error:
        return 0, 0
    return start, end


def _scan_chunk(path: str, fm: FileMap, pos: int, raw: bytes) -> ChunkRef:
    try:
        ref, records = parse_chunk(path, pos, raw)
    except CorruptChunkError as e:
        fm.problems.append(e)
        fm.corrupt_offsets.add(pos)
        ref = ChunkRef(pos, len(raw), *chunk_times(raw), "")
        fm.chunks.append(ref)
        return ref
    ids: set[int] = set()
    lo = hi = None
    for op, body in iter_records(records):
        if op == Opcode.MESSAGE:
            cid, _, t, _ = _MSG.unpack_from(body)
            ids.add(cid)
            fm.counts[cid] = fm.counts.get(cid, 0) + 1
            lo = t if lo is None or t < lo else lo
            hi = t if hi is None or t > hi else hi
        elif op in (Opcode.SCHEMA, Opcode.CHANNEL):
            _note(path, fm, pos, op, bytes(body))
    if lo is not None and hi is not None:
        fm.start_ns = lo if fm.start_ns is None else min(fm.start_ns, lo)
        fm.end_ns = hi if fm.end_ns is None else max(fm.end_ns, hi)
        ref.start_ns, ref.end_ns = lo, hi  # what it holds, whatever its header says
    ref.channel_ids = frozenset(ids)
    fm.chunks.append(ref)
    return ref


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
        if at + dlen > len(raw) or usize > _MAX_CHUNK:
            raise CorruptChunkError(path, f"chunk at offset {pos}: sizes beyond the record "
                                          f"({dlen} compressed, {usize} uncompressed bytes)")
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
    except (struct.error, UnicodeDecodeError, zstandard.ZstdError, RuntimeError, MemoryError) as e:
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
    """(opcode, body) of each record inside a decompressed chunk (or loose run)."""
    pos, n = 0, len(buf)
    unpack = _REC.unpack_from
    while pos + 9 <= n:
        op, length = unpack(buf, pos)
        body_at = pos + 9
        yield op, buf[body_at : body_at + length]
        pos = body_at + length


_MSG_REC = struct.Struct("<QHIQ")  # a message record after its opcode: length, channel, sequence, log time


def select_messages(records: memoryview, wanted: dict | frozenset, lo: int | None,
                    hi: int | None) -> list[tuple[int, int, int, memoryview]]:
    """(log time, channel id, sequence, payload view) of the messages of ``records`` (a
    decompressed chunk or loose run) on the channels ``wanted`` with lo <= log time < hi
    (None: unbounded). :func:`iter_records` and :data:`MSG_HEAD` in one pass: one unpack per
    record (its length and, for a message, its head), a payload view only for those kept."""
    out = []
    head, length_of, msg = _MSG_REC.unpack_from, _U64.unpack_from, Opcode.MESSAGE
    pos, n = 0, len(records)
    while pos + 9 <= n:
        if records[pos] == msg:
            length, cid, seq, t = head(records, pos + 1)
            if cid in wanted and (lo is None or t >= lo) and (hi is None or t < hi):
                out.append((t, cid, seq, records[pos + 9 + _MSG.size: pos + 9 + length]))
        else:
            length = length_of(records, pos + 1)[0]
        pos += 9 + length
    return out


def read_chunk(path: str, f: BinaryIO, ref: ChunkRef) -> memoryview:
    """Records of the chunk ``ref`` (CorruptChunkError when damaged)."""
    f.seek(ref.offset)
    raw = f.read(ref.length)
    if len(raw) != ref.length:
        raise CorruptChunkError(path, f"chunk at offset {ref.offset}: file ends inside it")
    if ref.loose:
        return memoryview(raw)
    return parse_chunk(path, ref.offset, raw)[1]


def read_message_index(path: str, f: BinaryIO, at: int, size: int) -> tuple[int, np.ndarray]:
    """(channel id, N x 2 array of (log time, offset in the chunk)) of the Message Index
    record at ``at`` (RecordingError when damaged)."""
    body = _read_record(path, f, at, size, Opcode.MESSAGE_INDEX)
    if len(body) < 6:
        raise _damaged(path, at, Opcode.MESSAGE_INDEX, "shorter than its header")
    (cid,) = _U16.unpack_from(body)
    (n,) = _U32.unpack_from(body, 2)
    if n % 16 or 6 + n > len(body):
        raise _damaged(path, at, Opcode.MESSAGE_INDEX, f"{n} bytes of entries in a {len(body)}-byte record")
    return cid, np.frombuffer(body, "<u8", n // 8, 6).reshape(-1, 2)


MSG_HEAD = _MSG
