"""MissionWriter: record timestamped streams to a chunked, indexed MCAP file.

One channel per stream (topic ``component/port``), ``log_time`` = ``publish_time`` = the
sample timestamp (int ns). Chunks go to the operating system as soon as they are full
(the file is opened unbuffered), and at least every ``flush_period_s`` of wall time, so a
process killed with SIGKILL leaves a file readable up to its last complete chunk. With
``threads=2`` (the default) chunks are compressed and written on a second thread, in order,
as soon as they are cut: the same bytes, the caller's thread free for the next chunk.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import Any

from ._codec import Codec
from ._errors import CodecError
from ._foreign import ForeignChannel, ForeignWriter
from ._mcapwriter import McapWriter
from ._mirror import FRAMES_MIRROR_OF, MIRROR_KEY, TRANSFORMS, Mirror
from ._registry import VERSION_KEY, CodecRegistry

__all__ = ["MissionWriter", "COMPRESSIONS"]

#: compression name -> MCAP chunk compression string
COMPRESSIONS = {"zstd": "zstd", "lz4": "lz4", "none": ""}
PROFILE = "impala-flow"


class _UnbufferedFile:
    """A write-through file: every chunk the mcap writer emits reaches the OS at once."""

    def __init__(self, path: str) -> None:
        self._f = open(path, "wb", buffering=0)  # noqa: SIM115 - closed by MissionWriter

    def write(self, data: bytes | memoryview) -> int:
        view, done = memoryview(data), 0
        while done < len(view):
            done += self._f.write(view[done:])
        return done

    def tell(self) -> int:
        return self._f.tell()

    def foreign_summary(self) -> dict[str, dict[str, Any]]:
        """Format -> what its writer wrote and could not write (counts)."""
        return {fw.profile: fw.summary() for fw in self._foreign}

    def flush(self) -> None:
        return None

    def close(self) -> None:
        self._f.close()


@dataclass
class _Topic:
    channel_id: int
    codec: Codec
    py_type: type
    strict: bool  # message types: refuse a value of another type
    mirror: Mirror | None
    mirror_id: int
    parts: Callable[[Any], list] | None = None  # codec's encode_parts, when it has one
    count: int = 0


class MissionWriter:
    """Write a mission to ``path`` (MCAP, chunked, indexed, with summary).

    ``codecs`` encodes every stream; ``metadata`` maps record names to string dicts
    ("how it was made": graph YAML, resolved parameters, plugin versions) and is written
    before any data. With ``foxglove=True`` every stream whose type has a mirror registered in
    ``codecs`` (:mod:`impala_flow.io._mirror`; the view plugin registers Foxglove schemas of poses,
    trajectories, grids, point sets, objects, detections and scans on ``/foxglove/<topic>``) is
    also written mirrored, and with ``json_views=True`` (the recorder's default) every other
    stream through the fallback mirror (the view plugin's: JSON there). Without mirrors
    registered, only the streams are written.

    ``foreign`` names output formats plugins register (:mod:`impala_flow.io._foreign`; the ros2
    plugin: ``ros2``, standard ROS 2 messages in CDR): every stream is also written in them, and
    with ``native=False`` only in them (no native channel, no mirror: a file other tools play back
    as it is, its header profile the format's). A format no plugin registers is a CodecError
    naming the plugin and its pip line.

    ``threads``: 2 compresses and writes each chunk on a second thread while the caller fills the
    next one (the file's bytes are the same as with 1; an error there is raised at the next
    write or at :meth:`close`, naming the file). :meth:`close` waits for it.
    """

    def __init__(self, path: str | os.PathLike[str], *, codecs: CodecRegistry,
                 compression: str = "zstd", chunk_size: int = 1 << 20,
                 metadata: dict[str, dict[str, str]] | None = None, foxglove: bool = True,
                 json_views: bool = False,
                 flush_period_s: float | None = 1.0, foreign: tuple[str, ...] = (), native: bool = True,
                 threads: int = 2) -> None:
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression must be one of {sorted(COMPRESSIONS)}, "
                             f"not {compression!r}")
        if threads not in (1, 2):
            raise ValueError(f"threads must be 1 or 2, not {threads!r}")
        if not native and not foreign:
            raise ValueError("native=False needs a foreign output format (nothing would be written)")
        self.path = os.fspath(path)
        self.codecs = codecs
        self.native = native
        self._foreign: list[ForeignWriter] = [codecs.foreign_writer(name) for name in foreign]
        self._foreign_ids: dict[ForeignChannel, int] = {}
        if not native:
            foxglove = json_views = False
        self.compression = compression
        self.foxglove = foxglove
        self.json_views = json_views
        self._flush_period_s = flush_period_s
        self._last_flush = time.monotonic()
        self._topics: dict[str, _Topic] = {}
        self._tf_id = 0
        self._tf: Mirror | None = None  # the frame-tree mirror, once its channel is declared
        self._schemas: dict[tuple[str, str, bytes], int] = {}
        self._file = _UnbufferedFile(self.path)
        self._mcap = McapWriter(self._file, int(chunk_size), COMPRESSIONS[compression], threads=threads,
                                name=self.path)
        self._mcap.start(profile=PROFILE if native else self._foreign[0].profile, library="impala-flow")
        self._closed = False
        for name, data in (metadata or {}).items():
            self.add_metadata(name, data)

    # --- declaration -----------------------------------------------------------------------

    def add_metadata(self, name: str, data: dict[str, Any]) -> None:
        """Store one metadata record; non-string values are stored as JSON."""
        self._mcap.add_metadata(str(name), {str(k): v if isinstance(v, str) else
                                            json.dumps(v, sort_keys=True, default=str)
                                            for k, v in data.items()})

    def _schema_id(self, name: str, encoding: str, data: bytes) -> int:
        key = (name, encoding, data)
        sid = self._schemas.get(key)
        if sid is None:
            sid = self._schemas[key] = self._mcap.register_schema(name, encoding, data)
        return sid

    def add_topic(self, topic: str, msg_type: type | None, child_frame: str = "") -> None:
        """Declare stream ``topic`` carrying values of ``msg_type`` (``None`` = NoneType);
        ``child_frame``: the frame its poses place on the frame tree (for the foreign formats)."""
        if topic in self._topics:
            raise ValueError(f"{self.path}: topic {topic!r} added twice")
        t = type(None) if msg_type is None else msg_type
        codec = self.codecs.for_type(t)
        cid = 0
        if self.native:
            sid = self._schema_id(codec.schema_name, codec.schema_encoding, codec.schema_data())
            cid = self._mcap.register_channel(
                topic, codec.message_encoding, sid,
                {VERSION_KEY: str(codec.schema_version)})
        for fw in self._foreign:
            for ch in fw.add_topic(topic, t, child_frame):
                self._foreign_channel(ch, topic)
        mirror = self.codecs.mirror_for(t, self.json_views) if self.foxglove else None
        mid = 0
        if mirror is not None:
            msid = self._schema_id(mirror.schema_name, mirror.schema_encoding, mirror.schema_data)
            mid = self._mcap.register_channel(mirror.topic_of(topic), mirror.message_encoding, msid,
                                              {MIRROR_KEY: topic})
        strict = codec.py_type is t and hasattr(t, "__impala_schema__")
        self._topics[topic] = _Topic(cid, codec, codec.py_type, strict, mirror, mid,
                                     getattr(codec, "encode_parts", None))

    def _foreign_channel(self, ch: ForeignChannel, of: str) -> int:
        """The channel id of a foreign writer's channel, registered when first seen."""
        cid = self._foreign_ids.get(ch)
        if cid is None:
            sid = self._schema_id(ch.schema_name, ch.schema_encoding, ch.schema_data)
            meta = dict(ch.metadata)
            if self.native:  # beside the streams: impala-flow's readers skip it as a mirror
                meta[MIRROR_KEY] = of
            cid = self._foreign_ids[ch] = self._mcap.register_channel(ch.topic, ch.message_encoding, sid, meta)
        return cid

    def _write_foreign(self, messages: Any, of: str) -> None:
        for ch, t_ns, payload in messages:
            self._mcap.add_message(self._foreign_channel(ch, of), t_ns, [payload], 0, cut=False)

    @property
    def topics(self) -> dict[str, type]:
        return {k: v.py_type for k, v in self._topics.items()}

    def count(self, topic: str) -> int:
        """Messages written so far on ``topic``."""
        return self._topics[topic].count

    # --- data ------------------------------------------------------------------------------

    def write(self, topic: str, t_ns: int, data: Any, seq: int = 0) -> None:
        """Write one sample (``t_ns``: int nanoseconds on the mission clock, >= 0)."""
        try:
            tp = self._topics[topic]
        except KeyError:
            raise KeyError(f"{self.path}: unknown topic {topic!r}; call add_topic first") \
                from None
        if tp.strict and type(data) is not tp.py_type and not isinstance(data, tp.py_type):
            raise CodecError(f"topic {topic!r} records {tp.py_type.__name__}, "
                             f"got {type(data).__name__}")
        if t_ns < 0:
            raise ValueError(f"topic {topic!r}: negative timestamp {t_ns} ns")
        seq &= 0xFFFFFFFF
        mirror = tp.mirror
        if self.native:
            parts = tp.parts(data) if tp.parts is not None else [tp.codec.encode(data)]  # bytes, arrays' memoryviews
            if mirror is not None and not self._foreign:  # the common case: the sample and its mirror, one call
                self._mcap.add_messages(tp.channel_id, t_ns, parts, seq, tp.mirror_id, mirror.convert(data, t_ns))
                mirror = None
            else:  # copies to follow (a mirror, foreign ones): into the sample's chunk, cut after them below
                self._mcap.add_message(tp.channel_id, t_ns, parts, seq, cut=mirror is None and not self._foreign)
        for fw in self._foreign:
            self._write_foreign(fw.write(topic, t_ns, data), topic)
        if mirror is not None:
            pb = mirror.convert(data, t_ns)
            self._mcap.add_message(tp.mirror_id, t_ns, [pb], seq, cut=False)
        if self._foreign or mirror is not None:
            self._mcap.cut_if_full()
        tp.count += 1
        if self._flush_period_s is not None:
            now = time.monotonic()
            if now - self._last_flush >= self._flush_period_s:
                self.flush()

    def write_transforms(self, t_ns: int, transforms: list[tuple[str, str, float, float, float, float]]) -> None:
        """Write planar frame transforms (parent, child, x, y, z, yaw) through the frame-tree
        mirror of ``codecs`` (key :data:`~impala_flow.io.TRANSFORMS`; the view plugin's:
        ``foxglove.FrameTransforms`` on ``/tf``); readers skip it like the other mirrors. Without
        that mirror registered, nothing is written. A foreign writer with a frame tree (ROS 2's
        ``/tf``) writes it instead of the mirror."""
        for fw in self._foreign:
            self._write_foreign(fw.write_transforms(t_ns, transforms), FRAMES_MIRROR_OF)
        if any(fw.frames for fw in self._foreign) or not self.foxglove:
            self._mcap.cut_if_full()
            return
        if self._tf is None:
            tf = self.codecs.mirror_for(TRANSFORMS)
            if tf is None:
                return
            sid = self._schema_id(tf.schema_name, tf.schema_encoding, tf.schema_data)
            self._tf_id = self._mcap.register_channel(tf.topic_of(FRAMES_MIRROR_OF), tf.message_encoding, sid,
                                                      {MIRROR_KEY: FRAMES_MIRROR_OF})
            self._tf = tf
        pb = self._tf.convert(transforms, t_ns)
        self._mcap.add_message(self._tf_id, t_ns, [pb], 0)  # cuts a full chunk, the foreign copies' too

    def foreign_summary(self) -> dict[str, dict[str, Any]]:
        """Format -> what its writer wrote and could not write (counts)."""
        return {fw.profile: fw.summary() for fw in self._foreign}

    @property
    def thread_cpu_s(self) -> float:
        """CPU seconds the second thread spent compressing and writing chunks (after :meth:`close`)."""
        return self._mcap.thread_cpu_s

    def flush(self) -> None:
        """Close the chunk in progress and hand it to the OS (fewer, bigger chunks compress
        better: the writer does this by itself when a chunk fills up)."""
        self._mcap.flush_chunk()
        self._last_flush = time.monotonic()

    def close(self) -> None:
        """Write the last chunk, the index and the summary; close the file. Idempotent."""
        if self._closed:
            return
        self._closed = True
        try:
            for fw in self._foreign:
                self._write_foreign(fw.finish(), "")
            self._mcap.finish()
        finally:
            try:
                self._mcap.stop_thread(raise_error=False)  # after an error above: nothing writes the file any more
            finally:
                self._file.close()

    def __enter__(self) -> MissionWriter:
        return self

    def __exit__(self, et: type[BaseException] | None, e: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
