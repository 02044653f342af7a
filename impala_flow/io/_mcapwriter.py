"""A lean MCAP writer: the hot path (message records into the chunk) without per-message
objects, every index and summary record written with :mod:`mcap.records`.

Why not ``mcap.writer.Writer``: it builds a ``Message`` object and five ``struct`` calls
per message and copies each payload three times; for small messages that overhead is
the whole cost. The file layout is the same (chunked, message indexes after each chunk,
summary with schemas, channels, statistics, chunk and metadata indexes, summary offsets,
footer CRC), and the tests read every file back with ``mcap.reader.make_reader``.
Schemas, channels and metadata are written between chunks, straight to the file, so a
damaged chunk never takes a channel definition with it.
"""

from __future__ import annotations

import struct
import zlib
from collections import defaultdict, deque
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import lz4.frame
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    ChunkIndex,
    DataEnd,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

from ._mcapfile import MAGIC

_MSG = struct.Struct("<BQHIQQ")  # opcode, length, channel, sequence, log_time, publish_time
_CHUNK = struct.Struct("<BQQQQI")  # opcode, length, start, end, uncompressed size, crc
_U32, _U64 = struct.Struct("<I"), struct.Struct("<Q")
_FOOTER = struct.Struct("<BQQQ")


class McapWriter:
    """Write MCAP records to ``stream`` (``write``/``tell``), chunking messages."""

    def __init__(self, stream: Any, chunk_size: int, compression: str) -> None:
        if compression not in ("zstd", "lz4", ""):
            raise ValueError(f"unknown compression {compression!r}")
        self._out = stream
        self._chunk_size = chunk_size
        self._compression = compression
        self._zstd = zstandard.ZstdCompressor() if compression == "zstd" else None
        self._buf = bytearray()
        self._index: dict[int, list[int]] = {}  # channel -> [t, offset, t, offset, ...]
        self._start = self._end = 0
        self._n_chunk = 0
        self.schemas: list[Schema] = []
        self.channels: list[Channel] = []
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self.counts: dict[int, int] = defaultdict(int)
        self.message_count = 0
        self._t_min = self._t_max = 0
        # chunks compressing on the worker thread, in file order: (future, chunk)
        self._pending: deque[tuple[Future, tuple[bytearray, int, int, dict[int, list[int]]]]] = deque()
        self._pool: ThreadPoolExecutor | None = None

    def _record(self, record: Any) -> tuple[int, int]:
        self.flush_chunk()  # the chunks made before this record first
        rb = RecordBuilder()
        record.write(rb)
        data = rb.end()
        at = self._out.tell()
        self._out.write(data)
        return at, len(data)

    def start(self, profile: str, library: str) -> None:
        self._out.write(MAGIC)
        self._record(Header(profile, library))

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        s = Schema(id=len(self.schemas) + 1, name=name, encoding=encoding, data=data)
        self.schemas.append(s)
        self._record(s)
        return s.id

    def register_channel(self, topic: str, message_encoding: str, schema_id: int,
                         metadata: dict[str, str]) -> int:
        c = Channel(id=len(self.channels) + 1, topic=topic, message_encoding=message_encoding,
                    metadata=dict(metadata), schema_id=schema_id)
        self.channels.append(c)
        self._record(c)
        return c.id

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        at, length = self._record(Metadata(name=name, metadata=data))
        self._metadata_indexes.append(MetadataIndex(offset=at, length=length, name=name))

    def add_message(self, channel_id: int, t_ns: int, parts: list, size: int,
                    seq: int) -> None:
        """Append one message whose payload is the concatenation of ``parts`` (``size``
        bytes): each part is copied once, into the chunk."""
        buf = self._buf
        off = len(buf)
        buf += _MSG.pack(Opcode.MESSAGE, 22 + size, channel_id, seq, t_ns, t_ns)
        for p in parts:
            buf += p
        idx = self._index.get(channel_id)
        if idx is None:
            idx = self._index[channel_id] = []
        idx += (t_ns, off)
        if self._n_chunk == 0:
            self._start = self._end = t_ns
        elif t_ns < self._start:
            self._start = t_ns
        elif t_ns > self._end:
            self._end = t_ns
        self._n_chunk += 1
        self.counts[channel_id] += 1
        if self.message_count == 0:
            self._t_min = self._t_max = t_ns
        elif t_ns < self._t_min:
            self._t_min = t_ns
        elif t_ns > self._t_max:
            self._t_max = t_ns
        self.message_count += 1
        if len(buf) >= self._chunk_size:
            self.flush_chunk(wait=False)

    def flush_chunk(self, wait: bool = True) -> None:
        """Close the chunk in progress (if any) and write it with its message indexes.

        Its CRC and compression run on a worker thread (zlib, zstd and lz4 release the GIL):
        with ``wait=False`` (a chunk that filled up) the call returns at once and the chunk is
        written when the next one fills, at the next record or at the latest by
        :meth:`finish`; ``wait=True`` writes every chunk pending. The file's bytes are the
        same either way: chunks and records are written in the order they were made."""
        if self._n_chunk:
            job = (self._buf, self._start, self._end, self._index)
            self._buf = bytearray()
            self._index = {}
            self._n_chunk = 0
            if self._pool is None:
                self._pool = ThreadPoolExecutor(1, thread_name_prefix="mcap-compress")
            self._pending.append((self._pool.submit(self._compress, job[0]), job))
        while self._pending and (wait or len(self._pending) > 1):
            future, (records, start, end, index) = self._pending.popleft()
            self._write_chunk(records, start, end, index, *future.result())

    def _compress(self, records: bytearray) -> tuple[int, bytes | bytearray]:
        crc = zlib.crc32(records)
        if self._zstd is not None:
            return crc, self._zstd.compress(records)
        if self._compression == "lz4":
            return crc, lz4.frame.compress(records)
        return crc, records

    def _write_chunk(self, records: bytearray, start: int, end: int, index: dict[int, list[int]], crc: int,
                     data: bytes | bytearray) -> None:
        comp = self._compression.encode()
        length = 8 + 8 + 8 + 4 + 4 + len(comp) + 8 + len(data)
        head = (_CHUNK.pack(Opcode.CHUNK, length, start, end, len(records), crc)
                + _U32.pack(len(comp)) + comp + _U64.pack(len(data)))
        out = self._out
        chunk_at = out.tell()
        out.write(head)
        out.write(data)
        index_at = chunk_at + len(head) + len(data)
        offsets: dict[int, int] = {}
        pieces = []
        pos = index_at
        for cid, pairs in index.items():
            body = struct.pack(f"<HI{len(pairs)}Q", cid, 8 * len(pairs), *pairs)
            rec = struct.pack("<BQ", Opcode.MESSAGE_INDEX, len(body)) + body
            offsets[cid] = pos
            pos += len(rec)
            pieces.append(rec)
        out.write(b"".join(pieces))
        self._chunk_indexes.append(ChunkIndex(
            message_start_time=start, message_end_time=end,
            chunk_start_offset=chunk_at, chunk_length=len(head) + len(data),
            message_index_offsets=offsets, message_index_length=pos - index_at,
            compression=self._compression, compressed_size=len(data),
            uncompressed_size=len(records)))

    def close(self) -> None:
        """Stop the compression thread (pending chunks are dropped: :meth:`finish` writes them)."""
        pool, self._pool = self._pool, None
        self._pending.clear()
        if pool is not None:
            pool.shutdown(wait=True)

    def finish(self) -> None:
        """Last chunk, data end, summary (with offsets and CRC), footer, magic."""
        self.flush_chunk()
        self.close()
        self._record(DataEnd(0))
        summary_at = self._out.tell()
        rb = RecordBuilder()
        groups: list[SummaryOffset] = []

        def group(opcode: int, records: list[Any]) -> None:
            start = rb.count
            for r in records:
                r.write(rb)
            if records:
                groups.append(SummaryOffset(group_opcode=opcode, group_start=summary_at + start,
                                            group_length=rb.count - start))

        stats = Statistics(
            message_count=self.message_count, schema_count=len(self.schemas),
            channel_count=len(self.channels), attachment_count=0,
            metadata_count=len(self._metadata_indexes), chunk_count=len(self._chunk_indexes),
            message_start_time=self._t_min, message_end_time=self._t_max,
            channel_message_counts=dict(self.counts))
        group(Opcode.SCHEMA, self.schemas)
        group(Opcode.CHANNEL, self.channels)
        group(Opcode.STATISTICS, [stats])
        group(Opcode.CHUNK_INDEX, self._chunk_indexes)
        group(Opcode.METADATA_INDEX, self._metadata_indexes)
        offsets_at = summary_at + rb.count
        for g in groups:
            g.write(rb)
        summary = rb.end()
        footer = _FOOTER.pack(Opcode.FOOTER, 20, summary_at, offsets_at)
        crc = zlib.crc32(footer, zlib.crc32(summary))
        self._out.write(summary + footer + _U32.pack(crc) + MAGIC)
