"""A lean MCAP writer: the hot path (message records into the chunk) without per-message
objects, every index and summary record written with :mod:`mcap.records`.

Why not ``mcap.writer.Writer``: it builds a ``Message`` object and five ``struct`` calls
per message and copies each payload three times; for small messages that overhead is
the whole cost. The file layout is the same (chunked, message indexes after each chunk,
summary with schemas, channels, statistics, chunk and metadata indexes, summary offsets,
footer CRC), and the tests read every file back with ``mcap.reader.make_reader``.
Schemas, channels and metadata are written between chunks, straight to the file, so a
damaged chunk never takes a channel definition with it.

With ``threads=2`` a full chunk is handed to a second thread that computes its CRC, compresses it
(zstd and lz4 release the GIL) and writes it with its message indexes, while the caller fills the
next one. Every record still reaches the file in the order it was made, and chunks are cut where
the caller cuts them, so the bytes are the same as with one thread. The hand-off is bounded:
:data:`QUEUE_JOBS` records or chunks waiting (at most that many chunks' bytes), then the caller waits.
A chunk is written as soon as it is handed over (never held until the next one fills), so a process
killed with SIGKILL loses at most the chunk being compressed besides the one in progress.
"""

from __future__ import annotations

import queue
import struct
import threading
import time
import weakref
import zlib
from collections import defaultdict
from collections.abc import Callable
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

#: zstd level of the chunks: 2 compresses a RADIATE import's 1 MB chunks in 4.2 ms instead of 6.0 (level 3, the
#: library's default) for files 0.8 % larger (ratio 4.32 against 4.36); level 1 is no faster and 13 % larger
ZSTD_LEVEL = 2
_MSG = struct.Struct("<BQHIQQ")  # opcode, length, channel, sequence, log_time, publish_time
_pack_msg, _OP_MESSAGE = _MSG.pack, int(Opcode.MESSAGE)  # the enum's attribute read once, not per message
_pack_msg_into, _HEAD = _MSG.pack_into, bytes(_MSG.size)  # a record's head, filled in once its payload is in
_CHUNK = struct.Struct("<BQQQQI")  # opcode, length, start, end, uncompressed size, crc
_U32, _U64 = struct.Struct("<I"), struct.Struct("<Q")
_FOOTER = struct.Struct("<BQQQ")
#: jobs (a chunk, or a record written between chunks) waiting for the writing thread before the caller waits
QUEUE_JOBS = 2


class _WritingThread:
    """Runs ``(function, args)`` jobs in submission order on one thread. The first error is kept and
    raised in the caller (with ``name``) at its next :meth:`submit` or at :meth:`stop`; the jobs after
    it are dropped, never run out of order."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.error: BaseException | None = None
        self.cpu_s = 0.0  # CPU time of the jobs run (the thread's own clock)
        self._q: queue.Queue = queue.Queue(maxsize=QUEUE_JOBS)
        self._thread = threading.Thread(target=self._run, name="impala-mcap-writer", daemon=True)
        self._thread.start()
        # a writer never closed still gets what it handed over written: when it is dropped, or at exit
        # (before daemon threads are stopped)
        self._drain = weakref.finalize(self, _drain, self._q, self._thread)

    def _run(self) -> None:
        while True:
            job = self._q.get()
            if job is None:
                return
            if self.error is None:
                c0 = time.thread_time()
                try:
                    job[0](*job[1])
                except BaseException as e:  # raised in the caller, named
                    self.error = e
                self.cpu_s += time.thread_time() - c0

    def _raise(self) -> None:
        e = self.error
        if e is not None:
            raise OSError(f"{self.name}: writing the recording failed: {type(e).__name__}: {e}") from e

    def submit(self, fn: Callable[..., Any], *args: Any) -> None:
        self._raise()
        self._q.put((fn, args))

    def stop(self) -> None:
        """Wait until every job submitted is written (or dropped after an error); raise that error."""
        self._drain()
        self._raise()


def _drain(q: queue.Queue, thread: threading.Thread) -> None:
    if thread.is_alive():
        q.put(None)
        thread.join()


class McapWriter:
    """Write MCAP records to ``stream`` (``write``/``tell``), chunking messages; ``threads=2``:
    chunks compressed and written on a second thread (module doc; ``name`` names the file in its
    errors). :meth:`finish` (or :meth:`stop_thread`) must be called before ``stream`` is closed."""

    def __init__(self, stream: Any, chunk_size: int, compression: str, threads: int = 1, name: str = "") -> None:
        if compression not in ("zstd", "lz4", ""):
            raise ValueError(f"unknown compression {compression!r}")
        if threads not in (1, 2):
            raise ValueError(f"threads must be 1 or 2, not {threads!r}")
        self._out = stream
        self._chunk_size = chunk_size
        self._compression = compression
        self._zstd = zstandard.ZstdCompressor(level=ZSTD_LEVEL) if compression == "zstd" else None
        self._buf = bytearray()
        self._index: dict[int, list[int]] = {}  # channel -> [t, offset, t, offset, ...]
        self.schemas: list[Schema] = []
        self.channels: list[Channel] = []
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self.counts: dict[int, int] = defaultdict(int)
        self.message_count = 0
        self._t_min = self._t_max = 0
        self._thread = _WritingThread(name or "mcap") if threads == 2 else None
        self.thread_cpu_s = 0.0  # CPU time the writing thread spent, known once it is stopped

    def _run(self, fn: Callable[..., Any], *args: Any) -> None:
        """``fn(*args)`` now, or on the writing thread after every job before it."""
        if self._thread is None:
            fn(*args)
        else:
            self._thread.submit(fn, *args)

    def stop_thread(self, raise_error: bool = True) -> None:
        """Write everything handed to the writing thread and end it, raising its error if any
        (``raise_error=False``: when another error is on its way already)."""
        th, self._thread = self._thread, None
        if th is not None:
            try:
                th.stop()
                self.thread_cpu_s = th.cpu_s
            except OSError:
                if raise_error:
                    raise

    def _write(self, data: bytes, metadata_name: str | None = None) -> None:
        at = self._out.tell()
        self._out.write(data)
        if metadata_name is not None:
            self._metadata_indexes.append(MetadataIndex(offset=at, length=len(data), name=metadata_name))

    def _record(self, record: Any, metadata_name: str | None = None) -> None:
        rb = RecordBuilder()
        record.write(rb)
        self._run(self._write, rb.end(), metadata_name)

    def start(self, profile: str, library: str) -> None:
        self._run(self._write, MAGIC)
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
        self._record(Metadata(name=name, metadata=data), name)

    def add_message(self, channel_id: int, t_ns: int, parts: list, seq: int, cut: bool = True) -> None:
        """Append one message whose payload is the concatenation of ``parts`` (bytes or any
        buffers, each copied once, into the chunk; its length is known once they are in, and
        written into the record's head then). Nothing else per message: the chunk's time span
        and the counts are taken from its index when it is cut. ``cut=False`` leaves a full chunk
        open (the next message's copies follow it into the same chunk: :meth:`cut_if_full`)."""
        buf = self._buf
        idx = self._index.get(channel_id)
        if idx is None:
            idx = self._index[channel_id] = []
        off = len(buf)
        idx += (t_ns, off)
        buf += _HEAD
        for p in parts:
            buf += p
        _pack_msg_into(buf, off, _OP_MESSAGE, len(buf) - off - 9, channel_id, seq, t_ns, t_ns)
        if cut and len(buf) >= self._chunk_size:
            self.flush_chunk()

    def cut_if_full(self) -> None:
        """Cut the chunk in progress if it has reached the chunk size."""
        if len(self._buf) >= self._chunk_size:
            self.flush_chunk()

    def add_messages(self, channel_id: int, t_ns: int, parts: list, seq: int, channel_id2: int,
                     payload2: bytes) -> None:
        """:meth:`add_message` of two messages of the same time and sequence (a sample and its
        mirror), the second's payload one buffer: one call from the writer instead of two. Both
        land in the same chunk: a file cut short keeps a sample with its mirror or neither."""
        self.add_message(channel_id, t_ns, parts, seq, cut=False)
        buf, index = self._buf, self._index
        idx = index.get(channel_id2)
        if idx is None:
            idx = index[channel_id2] = []
        idx += (t_ns, len(buf))
        buf += _pack_msg(_OP_MESSAGE, 22 + len(payload2), channel_id2, seq, t_ns, t_ns)
        buf += payload2
        if len(buf) >= self._chunk_size:
            self.flush_chunk()

    def flush_chunk(self) -> None:
        """Write the chunk in progress (if any) and its message indexes."""
        index = self._index
        if not index:
            return
        counts = self.counts
        start = end = None
        n_chunk = 0
        for cid, pairs in index.items():  # in order of first message: the statistics' order as when counted one by one
            times = pairs[0::2]
            n = len(times)
            counts[cid] += n
            n_chunk += n
            lo, hi = min(times), max(times)
            if start is None or lo < start:
                start = lo
            if end is None or hi > end:
                end = hi
        if self.message_count == 0 or start < self._t_min:
            self._t_min = start
        if self.message_count == 0 or end > self._t_max:
            self._t_max = end
        self.message_count += n_chunk
        self._run(self._write_chunk, self._buf, index, start, end)
        self._buf = bytearray()
        self._index = {}

    def _write_chunk(self, records: bytearray, index: dict[int, list[int]], start: int, end: int) -> None:
        crc = zlib.crc32(records)
        if self._zstd is not None:
            data: bytes | bytearray = self._zstd.compress(records)
        elif self._compression == "lz4":
            data = lz4.frame.compress(records)
        else:
            data = records
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

    def finish(self) -> None:
        """Last chunk, data end, summary (with offsets and CRC), footer, magic."""
        try:
            self.flush_chunk()
        except BaseException:
            self.stop_thread(raise_error=False)
            raise
        self.stop_thread()
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
