"""MissionReader: decode a recorded mission, streaming chunk by chunk through the index.

Any valid MCAP file reads, whoever wrote it. A file whose summary is complete (chunk index,
statistics, nothing outside the indexed chunks) is mapped through it, so
:meth:`MissionReader.messages` seeks by time without reading what it skips. Any other file
(no summary, no chunk or message index, no statistics, messages outside chunks, a damaged
summary, or a file cut short because its recorder was SIGKILLed) is mapped by one forward
scan, every chunk CRC-checked; :meth:`MissionReader.info` then says ``truncated`` and how
many messages were recovered. Messages come in (log time, file order) order, as the
official ``mcap`` reader gives them once sorted by log time.

Bad files raise one :class:`~impala_flow.io._errors.RecordingError` subclass with a one-line
message naming the file and what is wrong. With ``strict=False`` (default) whatever is still
valid stays readable: a truncated file is recovered, a damaged record or a corrupt chunk is
skipped and listed in ``info().problems`` (one line naming the file and the offset), and the
messages a corrupt chunk held are counted per stream in :attr:`MissionReader.losses` (from
the chunk's message indexes: how many, on which topic, between which times); with
``strict=True`` both raise.
"""

from __future__ import annotations

import heapq
import logging
import os
import stat
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from . import _mcapfile as mf
from ._adapter import AdaptedChannel, AdapterContext, ChannelAdapter
from ._codec import SCHEMA_ENCODING, Codec
from ._errors import (
    CodecError,
    CorruptChunkError,
    RecordingError,
    SchemaMismatchError,
    TruncatedRecordingError,
    UnknownSchemaError,
)
from ._mirror import MIRROR_KEY
from ._registry import CodecRegistry

__all__ = ["MissionReader", "RecordingInfo", "ChannelInfo", "Recorded", "Loss"]

log = logging.getLogger(__name__)

#: how much earlier than its message's log time an adapted sample may be and still come in time order
#: (a rosbag2 logs a radar turn when it is complete: its beams are up to a turn earlier)
REORDER_WINDOW_S = 2.0
#: samples held at most while putting adapted samples in order (beyond: the earliest are given)
REORDER_MAX_SAMPLES = 200_000


@dataclass(frozen=True)
class _Adapted:
    """The samples a channel adapter made of one message: ``((t_ns, value), ...)``."""

    samples: list[tuple[int, Any]]


class Recorded(NamedTuple):
    """One recorded sample: topic, timestamp (int ns), decoded value, sequence number."""

    topic: str
    t_ns: int
    data: Any
    seq: int


@dataclass(frozen=True)
class ChannelInfo:
    topic: str
    schema: str
    schema_encoding: str
    message_encoding: str
    count: int
    rate_hz: float  # (count - 1) / recording duration: mean rate over the whole mission
    mirror_of: str | None  # set on mirror channels (the view plugin's Foxglove ones)
    decodable: bool  # a codec of the registry reads it


@dataclass(frozen=True)
class Loss:
    """Messages a damaged chunk held that cannot be read: ``count`` messages of ``topic``
    stamped from ``start_ns`` to ``end_ns``; ``topic``/``count`` None when the file has no
    message index to say (the chunk's time range is then that of the chunk header)."""

    topic: str | None
    count: int | None
    start_ns: int
    end_ns: int
    offset: int  # of the chunk in the file

    def __str__(self) -> str:
        n = "an unknown number of" if self.count is None else str(self.count)
        on = "unknown topics" if self.topic is None else repr(self.topic)
        return (f"{n} messages of {on} lost (t={self.start_ns * 1e-9:.3f}..{self.end_ns * 1e-9:.3f} s, "
                f"chunk at offset {self.offset})")


@dataclass(frozen=True)
class RecordingInfo:
    """What ``impala-flow info`` prints."""

    path: str
    size_bytes: int
    channels: tuple[ChannelInfo, ...]
    message_count: int
    start_ns: int | None
    end_ns: int | None
    compression: str  # "zstd", "lz4", "none", or "zstd+lz4" when mixed
    chunk_count: int
    truncated: bool
    recovered_count: int | None  # recorded messages recovered from a truncated file (no mirrors)
    corrupt_chunks: int
    problems: tuple[str, ...]
    metadata: dict[str, dict[str, str]]
    library: str
    profile: str
    mirror_count: int = 0  # of message_count, the mirror copies
    attachments: tuple[tuple[str, str, int], ...] = ()  # name, media type, bytes
    verified: bool = False  # counts are readable messages, every CRC and index checked

    @property
    def complete(self) -> bool:
        """Not truncated and no problem found."""
        return not self.truncated and not self.problems and not self.corrupt_chunks

    @property
    def duration_ns(self) -> int:
        if self.start_ns is None or self.end_ns is None:
            return 0
        return self.end_ns - self.start_ns

    @property
    def duration_s(self) -> float:
        return self.duration_ns * 1e-9


class MissionReader:
    """Read the mission recorded in ``path`` with the codecs of ``codecs``.

    Opening reads only the header, footer and summary (or, for a cut file, scans it once).
    Use as a context manager, or call :meth:`close`.
    """

    def __init__(self, path: str | os.PathLike[str], codecs: CodecRegistry | None = None, *,
                 strict: bool = False, adapter_params: dict[str, Any] | None = None,
                 reorder_window_s: float = REORDER_WINDOW_S) -> None:
        self.path = os.fspath(path)
        #: options given to every channel adapter (:mod:`impala_flow.io._adapter`)
        self.adapter_params = dict(adapter_params or {})
        self._window_ns = int(round(reorder_window_s * 1e9))
        #: topic -> adapted samples dropped for coming later than the reordering window allows
        self.late: dict[str, int] = {}
        self.codecs = codecs if codecs is not None else CodecRegistry.with_standard_types()
        self.strict = strict
        try:
            kind = os.stat(self.path).st_mode  # before open(): opening a FIFO would block
        except OSError as e:
            raise RecordingError(self.path, f"cannot open ({e.strerror})") from None
        if not stat.S_ISREG(kind):
            what = "a directory" if stat.S_ISDIR(kind) else "a FIFO" if stat.S_ISFIFO(kind) else \
                "not a regular file"
            raise RecordingError(self.path, f"{what}, not an MCAP recording")
        try:
            self._f = open(self.path, "rb")  # noqa: SIM115 - closed by close()
        except OSError as e:
            raise RecordingError(self.path, f"cannot open ({e.strerror})") from None
        try:
            self._map = self._open()
        except BaseException:
            self._f.close()
            raise
        self._codecs: dict[int, Codec | ChannelAdapter | UnknownSchemaError] = {}
        self.undecodable: dict[str, UnknownSchemaError] = {}
        self.losses: list[Loss] = []  # messages of damaged chunks met so far (each once)
        self._lost_keys: set[tuple[int, int | None]] = set()
        self._verified: dict[int, int] | None = None

    def _open(self) -> mf.FileMap:
        size = os.fstat(self._f.fileno()).st_size
        mf.check_magic(self.path, self._f, size)
        try:
            fm = mf.read_indexed(self.path, self._f, size)
        except RecordingError as e:  # corrupt summary: recover by scanning
            if self.strict:
                raise
            fm = mf.scan(self.path, self._f, size, truncated=not mf.footer_ok(self._f, size))
            fm.problems.insert(0, e)
            return fm
        if fm is not None:
            if not sum(fm.counts.values()):
                fm.start_ns = fm.end_ns = None
            return fm
        fm = mf.scan(self.path, self._f, size, truncated=not mf.footer_ok(self._f, size))
        if fm.truncated and self.strict:
            raise TruncatedRecordingError(
                self.path, f"truncated recording (no footer/summary); "
                           f"{sum(fm.counts.values())} messages recoverable")
        if self.strict and fm.problems:
            raise fm.problems[0]
        if fm.truncated:
            log.info("%s: truncated recording, %d messages recovered", self.path,
                     sum(fm.counts.values()))
        for p in fm.problems:
            log.warning("%s", p)
        return fm

    # --- description -----------------------------------------------------------------------

    def _codec(self, cid: int) -> Codec | ChannelAdapter | UnknownSchemaError:
        c = self._codecs.get(cid)
        if c is None:
            ch = self._map.channels[cid]
            s = self._map.schemas.get(ch.schema_id)
            try:
                if s is None:
                    raise UnknownSchemaError(ch.topic, "<no schema>", None)
                make = self.codecs.adapter_for(s.encoding, s.name, ch.message_encoding)
                if make is not None:
                    c = self._adapter(make, self._foreign(cid))
                else:
                    c = self.codecs.for_channel(ch.topic, s.name, s.encoding, s.data,
                                                ch.message_encoding, ch.metadata)
            except UnknownSchemaError as e:
                c = e
                if s is not None and s.encoding != SCHEMA_ENCODING and self.codecs.missing_plugins \
                        and not isinstance(e, SchemaMismatchError):
                    c = UnknownSchemaError(ch.topic, s.name, None, f"{s.encoding!r} schema, "
                                           f"{ch.message_encoding!r} messages: no codec nor channel adapter; "
                                           + "; ".join(self.codecs.missing_plugins))
            self._codecs[cid] = c
        return c

    def _foreign(self, cid: int) -> AdaptedChannel:
        ch = self._map.channels[cid]
        s = self._map.schemas.get(ch.schema_id)
        return AdaptedChannel(ch.topic, s.name if s else "", s.encoding if s else "", bytes(s.data) if s else b"",
                              ch.message_encoding, dict(ch.metadata))

    def _adapter(self, make: Any, channel: AdaptedChannel) -> ChannelAdapter:
        def head(topic: str, n: int) -> list[tuple[bytes, int]]:
            return [(m.data, m.t_ns) for _, m in zip(range(n), self.messages([topic], raw=True), strict=False)]

        context = AdapterContext(self.path, tuple(self._foreign(cid) for cid in sorted(self._map.channels)),
                                 head, self.adapter_params)
        try:
            return make(channel, context)
        except ValueError as e:
            raise UnknownSchemaError(channel.topic, channel.schema_name, None, str(e)) from None

    def adapters(self) -> dict[str, ChannelAdapter]:
        """Topic -> the adapter reading it, for the channels read through one so far."""
        return {self._map.channels[cid].topic: c for cid, c in self._codecs.items()
                if hasattr(c, "adapt")}

    def skipped_counts(self) -> dict[str, int]:
        """Topic -> messages of the channels no codec or adapter reads (skipped when reading every topic)."""
        counts = self._map.counts if self._verified is None else self._verified
        return {ch.topic: counts.get(cid, 0) for cid, ch in sorted(self._map.channels.items())
                if MIRROR_KEY not in ch.metadata and isinstance(self._codec(cid), UnknownSchemaError)}

    @property
    def topics(self) -> dict[str, str]:
        """Recorded topics (mirrors excluded) -> schema name."""
        out = {}
        for ch in self._map.channels.values():
            if MIRROR_KEY not in ch.metadata:
                s = self._map.schemas.get(ch.schema_id)
                out[ch.topic] = s.name if s else ""
        return out

    def topic_type(self, topic: str) -> type:
        """The Python type decoded on ``topic`` (UnknownSchemaError if no codec reads it)."""
        c = self._codec(self._channel_id(topic))
        if isinstance(c, UnknownSchemaError):
            raise c
        return getattr(c, "value_type", None) or c.py_type  # type: ignore[union-attr]  # an older version's codec decodes to the current type

    def _channel_id(self, topic: str) -> int:
        for cid, ch in self._map.channels.items():
            if ch.topic == topic:
                return cid
        raise KeyError(f"{self.path}: no topic {topic!r} (recorded: {sorted(self.topics)})")

    def info(self) -> RecordingInfo:
        """What the file holds. Counts are those of the summary's statistics (or of the scan)
        until :meth:`verify` ran; then they are the messages actually readable."""
        fm = self._map
        counts = fm.counts if self._verified is None else self._verified
        total = sum(counts.values())
        dur_s = ((fm.end_ns or 0) - (fm.start_ns or 0)) * 1e-9
        chans = []
        mirrors = 0
        for cid, ch in sorted(fm.channels.items()):
            s = fm.schemas.get(ch.schema_id)
            n = counts.get(cid, 0)
            mirror = ch.metadata.get(MIRROR_KEY)
            mirrors += n if mirror else 0
            chans.append(ChannelInfo(
                ch.topic, s.name if s else "", s.encoding if s else "", ch.message_encoding,
                n, max(n - 1, 0) / dur_s if dur_s > 0 else 0.0, mirror,
                not isinstance(self._codec(cid), UnknownSchemaError)))
        chunks = [c for c in fm.chunks if not c.loose]
        comps = sorted({c.compression or "none" for c in chunks if c.offset not in fm.corrupt_offsets})
        return RecordingInfo(
            path=self.path, size_bytes=fm.size, channels=tuple(chans), message_count=total,
            start_ns=fm.start_ns, end_ns=fm.end_ns, compression="+".join(comps) or "none",
            chunk_count=len(chunks), truncated=fm.truncated,
            recovered_count=total - mirrors if fm.truncated else None,
            corrupt_chunks=len(fm.corrupt_offsets),
            problems=tuple(str(p) for p in fm.problems), metadata=dict(fm.metadata),
            library=fm.header.library if fm.header else "",
            profile=fm.header.profile if fm.header else "", mirror_count=mirrors,
            attachments=tuple(a[:3] for a in fm.attachments), verified=self._verified is not None)

    def verify(self) -> list[str]:
        """Read every chunk and check it against everything that describes it: its CRC, its
        header's times, its message indexes (every entry points at a message of that channel
        and time, every message has its entry), the chunk index and the statistics; count
        the readable messages per channel (:meth:`info` then reports those). Returns every
        problem found, each once (an empty list: the file is whole)."""
        from ._verify import verify_file

        self._verified, problems = verify_file(self.path, self._f, self._map)
        return problems

    # --- messages --------------------------------------------------------------------------

    def messages(self, topics: Iterable[str] | None = None, start_ns: int | None = None,
                 end_ns: int | None = None, *, raw: bool = False, finish: bool = True) -> Iterator[Recorded]:
        """Samples with ``start_ns <= t_ns < end_ns`` in (t_ns, file order) order.

        ``topics=None`` reads every channel a codec reads (channels of unknown schema are
        skipped and listed in :attr:`undecodable`; Foxglove mirrors are skipped); naming a
        topic whose schema is unknown raises UnknownSchemaError. ``raw=True`` yields the
        payload bytes undecoded. Only the chunks overlapping the time range are read. The
        messages of a damaged chunk are skipped and counted in :attr:`losses`. Channel adapters
        holding samples back (``finish()``: a turn waits for the next one's stamp) give them at the
        end, unless ``finish`` is False (a part of a split recording that more parts follow).
        """
        merged, wanted = self._records(topics, start_ns, end_ns, raw)
        if any(hasattr(d, "adapt") for _, d in wanted.values()):
            return self._reorder(self._finish(merged, wanted) if finish else merged)
        return merged

    def _records(self, topics: Iterable[str] | None, start_ns: int | None, end_ns: int | None,
                 raw: bool) -> tuple[Iterator[Recorded], dict[int, tuple[str, Any]]]:
        """The chunks' messages merged by log time (adapted ones not yet in order), and the channels read."""
        wanted = self._select(topics, raw)
        refs = [r for r in self._map.chunks
                if (start_ns is None or r.end_ns >= start_ns)
                and (end_ns is None or r.start_ns < end_ns)
                and (r.channel_ids is None or not r.channel_ids.isdisjoint(wanted))]
        refs.sort(key=lambda r: (r.start_ns, r.offset))
        return self._merge(refs, wanted, start_ns, end_ns), wanted

    def _finish(self, records: Iterator[Recorded], wanted: dict[int, tuple[str, Any]]) -> Iterator[Recorded]:
        """``records``, then what each adapter still holds (its ``finish()``)."""
        last = None
        for r in records:
            last = r.t_ns
            yield r
        for topic, d in wanted.values():
            if hasattr(d, "finish"):
                samples = list(d.finish())
                if samples:
                    yield Recorded(topic, last if last is not None else samples[0][0], _Adapted(samples), 0)

    def _reorder(self, records: Iterator[Recorded]) -> Iterator[Recorded]:
        """Adapted samples (each with its own time) and native ones in time order: held in a heap
        until the log time has passed them by the reordering window (at most
        :data:`REORDER_MAX_SAMPLES` held); one still earlier than a sample given is dropped and
        counted in :attr:`late`."""
        heap: list[tuple[int, int, str, Any, int]] = []
        n, last = 0, None
        push, pop = heapq.heappush, heapq.heappop
        for r in records:
            entries = r.data.samples if isinstance(r.data, _Adapted) else ((r.t_ns, r.data),)
            for t, v in entries:
                if last is not None and t < last:
                    self.late[r.topic] = self.late.get(r.topic, 0) + 1
                    continue
                push(heap, (t, n, r.topic, v, r.seq))
                n += 1
            horizon = r.t_ns - self._window_ns
            while heap and (heap[0][0] <= horizon or len(heap) > REORDER_MAX_SAMPLES):
                t, _, topic, v, seq = pop(heap)
                last = t
                yield Recorded(topic, t, v, seq)
        while heap:
            t, _, topic, v, seq = pop(heap)
            yield Recorded(topic, t, v, seq)

    def lost_counts(self) -> dict[str, int | None]:
        """Topic -> messages lost so far (None: some of unknown count); ``"?"``: losses
        whose topic the file cannot tell (no message index)."""
        out: dict[str, int | None] = {}
        for loss in self.losses:
            key = loss.topic or "?"
            prev = out.get(key, 0)
            out[key] = None if prev is None or loss.count is None else prev + loss.count
        return out

    def _select(self, topics: Iterable[str] | None, raw: bool) -> dict[int, tuple[str, Any]]:
        wanted: dict[int, tuple[str, Any]] = {}
        if topics is None:
            for cid, ch in self._map.channels.items():
                if MIRROR_KEY in ch.metadata and not raw:
                    continue
                c = self._codec(cid)
                if raw:
                    wanted[cid] = (ch.topic, None)
                elif isinstance(c, UnknownSchemaError):
                    if self.strict:
                        raise c
                    if ch.topic not in self.undecodable:
                        log.warning("%s: %s; channel skipped", self.path, c)
                    self.undecodable[ch.topic] = c
                else:
                    wanted[cid] = (ch.topic, c if hasattr(c, "adapt") else c.decode)
            return wanted
        for topic in [topics] if isinstance(topics, str) else topics:
            cid = self._channel_id(topic)
            c = self._codec(cid)
            if not raw and isinstance(c, UnknownSchemaError):
                raise c
            wanted[cid] = (topic, None if raw else c if hasattr(c, "adapt") else c.decode)  # type: ignore
        return wanted

    def _load(self, ref: mf.ChunkRef) -> memoryview | None:
        if ref.offset in self._map.corrupt_offsets:
            return None
        try:
            return mf.read_chunk(self.path, self._f, ref)
        except CorruptChunkError as e:
            if self.strict:
                raise
            self._map.corrupt_offsets.add(ref.offset)
            self._map.problems.append(e)
            log.warning("%s (skipped)", e)
            return None

    def _count_loss(self, ref: mf.ChunkRef, wanted: dict[int, tuple[str, Any]],
                    lo: int | None, hi: int | None) -> None:
        """Record in :attr:`losses` the wanted messages of the damaged chunk ``ref`` that
        fall in [lo, hi), from its message indexes (each chunk and channel once)."""
        known: set[int] = set()
        for cid, at in sorted(ref.index.items()):
            try:
                cid, entries = mf.read_message_index(self.path, self._f, at, self._map.size)
            except RecordingError:
                continue
            known.add(cid)
            if cid not in wanted or (ref.offset, cid) in self._lost_keys:
                continue
            t = entries[:, 0].astype(np.int64)
            t = t[((lo is None) | (t >= (lo or 0))) & ((hi is None) | (t < (hi or 0)))]
            if len(t):
                self._lost_keys.add((ref.offset, cid))
                self.losses.append(Loss(wanted[cid][0], len(t), int(t.min()), int(t.max()), ref.offset))
        if not known and (ref.offset, None) not in self._lost_keys:
            self._lost_keys.add((ref.offset, None))
            start = ref.start_ns if lo is None else max(ref.start_ns, lo)
            end = ref.end_ns if hi is None else min(ref.end_ns, hi - 1)
            topic = wanted[next(iter(wanted))][0] if len(wanted) == 1 else None
            self.losses.append(Loss(topic, None, start, max(start, end), ref.offset))

    def _chunk_messages(self, ref: mf.ChunkRef, wanted: dict[int, tuple[str, Any]],
                        lo: int | None, hi: int | None) -> list[tuple[int, int, int, Any]]:
        """(t_ns, channel id, seq, payload view) of the wanted messages of one chunk."""
        records = self._load(ref)
        if records is None:
            self._count_loss(ref, wanted, lo, hi)
            return []
        return mf.select_messages(records, wanted, lo, hi)

    def _emit(self, item: tuple[int, int, int, Any], wanted: dict) -> Recorded:
        t, cid, seq, payload = item
        topic, decode = wanted[cid]
        if decode is None:
            return Recorded(topic, t, bytes(payload), seq)
        try:
            if hasattr(decode, "adapt"):  # a channel adapter: the message's samples, put in order by _reorder
                return Recorded(topic, t, _Adapted(list(decode.adapt(payload, t))), seq)
            return Recorded(topic, t, decode(payload), seq)
        except ValueError as e:
            raise CodecError(f"{self.path}: topic {topic!r} at t={t} ns: {e}") from None
        except CodecError as e:
            raise CodecError(f"{self.path}: topic {topic!r} at t={t} ns: {e}") from None

    def _merge(self, refs: list[mf.ChunkRef], wanted: dict, lo: int | None,
               hi: int | None) -> Iterator[Recorded]:
        """k-way merge of chunks by (time, file order); a chunk is read only when its turn
        comes (``refs`` sorted by (start time, offset))."""
        heap: list[tuple[int, int, int, tuple]] = []
        n = len(refs)
        # every channel decoded by a codec (no adapter, not raw): the chunks' messages decoded inline
        plain = all(d is not None and not hasattr(d, "adapt") for _, d in wanted.values())
        for i, ref in enumerate(refs):
            while heap and heap[0][0] < ref.start_ns:  # earlier than anything still unread
                yield self._emit(heapq.heappop(heap)[3], wanted)
            items = self._chunk_messages(ref, wanted, lo, hi)
            times = [it[0] for it in items]
            ordered = all(a <= b for a, b in zip(times, times[1:], strict=False))
            nxt = refs[i + 1] if i + 1 < n else None
            if not heap and ordered and (nxt is None or ref.end_ns < nxt.start_ns or (
                    ref.end_ns == nxt.start_ns and ref.offset < nxt.offset)):
                if not plain:
                    for it in items:  # fast path: no overlap with what comes next
                        yield self._emit(it, wanted)
                    continue
                for t, cid, seq, payload in items:  # the same, decoded inline (as _emit)
                    topic, decode = wanted[cid]
                    try:
                        data = decode(payload)
                    except (ValueError, CodecError) as e:
                        raise CodecError(f"{self.path}: topic {topic!r} at t={t} ns: {e}") from None
                    yield Recorded(topic, t, data, seq)
                continue
            for k, it in enumerate(items):
                heapq.heappush(heap, (it[0], ref.offset, k, it))
        while heap:
            yield self._emit(heapq.heappop(heap)[3], wanted)

    # --- lifecycle -------------------------------------------------------------------------

    def metadata(self) -> dict[str, dict[str, str]]:
        return dict(self._map.metadata)

    def close(self) -> None:
        self._f.close()

    def __enter__(self) -> MissionReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
