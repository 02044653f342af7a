"""io.Replayer (the engine's own component): a recorded mission as a source; recorded topics become output ports."""

from __future__ import annotations

import fnmatch
import logging
import os
from collections.abc import Iterator
from typing import Any

from .._component import Component, Input, Output, Param, Source
from ._bag import BagReader, open_recording
from ._errors import UnknownSchemaError
from ._reader import MissionReader
from ._runcodecs import run_codecs

__all__ = ["Replayer", "TIME_JUMP"]

log = logging.getLogger(__name__)

#: output announcing a loop: data = offset (int ns) added to recorded times from then on
TIME_JUMP = "time_jump"


def _select(reader: MissionReader | BagReader, streams: list[str], rename: dict[str, str]) -> dict[str, str]:
    """Recorded topic -> output port, for the decodable topics matching ``streams``."""
    recorded = list(reader.topics)
    chosen: list[str] = []
    for pattern in streams or ["*"]:
        hits = [t for t in recorded if fnmatch.fnmatchcase(t, pattern)]
        if not hits:
            raise ValueError(f"{reader.path}: stream {pattern!r} matches no recorded topic "
                             f"(recorded: {', '.join(sorted(recorded))})")
        explicit = not any(c in pattern for c in "*?[")
        for t in hits:
            try:
                reader.topic_type(t)
            except UnknownSchemaError:
                if explicit:
                    raise
                log.warning("%s: topic %r skipped: no codec for its schema", reader.path, t)
                continue
            if t not in chosen:
                chosen.append(t)
    unknown = set(rename) - set(recorded)
    if unknown:
        raise ValueError(f"rename: no recorded topic {sorted(unknown)}")
    ports = {t: str(rename.get(t, t)) for t in chosen}
    if len(set(ports.values())) != len(ports) or TIME_JUMP in ports.values():
        raise ValueError(f"rename: output names must be unique and not {TIME_JUMP!r}")
    return ports


class Replayer(Source):
    """Replays the recording ``path``: every selected topic is an output port.

    ``streams`` selects topics (glob patterns, default all), ``rename`` maps a recorded
    topic to another port name. ``start_s``/``end_s`` are seconds from the recording's first
    sample: the replay seeks there through the MCAP index, never scanning what it skips.
    Memory is bounded: samples stream chunk by chunk. Pacing (``speed``) is the clock's
    job. With ``loops`` > 1 (0 = forever) the mission is replayed again, shifted so that
    mission time keeps increasing; each jump is announced on output ``time_jump`` (the
    offset in ns) and by calling ``on_time_jump(offset_ns)`` of every component
    downstream, after everything earlier than the jump has been processed. A truncated
    recording replays what it holds. Messages a damaged chunk held are never silent: they
    are counted per output (``summary()["lost"]``, from the file's message indexes) with the
    time ranges missing (``summary()["lost_ranges_s"]``, seconds from the first sample), and
    logged as a warning. Foreign channels (a rosbag2's ROS 2 messages) are read through the channel
    adapters plugins register (:mod:`impala_flow.io._adapter`), with ``adapter_params``; the summary
    counts the messages of channels nothing reads (``skipped``, by topic), adapted samples dropped
    for coming too late to be put in order (``late``) and says how adapters made their samples
    (``adapted``). A ``start_s`` past the end of the recording is refused when the run starts.
    """

    path = Param(str, path="read", doc="MCAP recording, or a rosbag2 folder of split MCAP files")
    streams = Param(list, default=[], doc="topics to replay (glob patterns); empty = all")
    rename = Param(dict, default={}, doc="recorded topic -> output port name")
    start_s = Param(float, default=0.0, ge=0.0, doc="seconds after the first sample to start at")
    end_s = Param(float, default=0.0, ge=0.0, doc="seconds after the first sample to stop at "
                                                   "(0 = the end)")
    loops = Param(int, default=1, ge=0, doc="number of passes (0 = forever)")
    adapter_params = Param(dict, default={}, doc="options of the channel adapters reading foreign channels "
                                                   "(a rosbag2's ROS 2 messages), e.g. range_resolution_m")

    @classmethod
    def declare_ports(cls, params: dict[str, Any]) -> tuple[dict[str, Input], dict[str, Output]]:
        start, end = params.get("start_s", 0.0), params.get("end_s", 0.0)
        if end > 0 and end <= start:  # checked at validation: the graph never starts
            raise ValueError(f"end_s {end} <= start_s {start}: nothing would be replayed")
        with open_recording(params["path"], run_codecs(), adapter_params=params.get("adapter_params") or {}) as r:
            ports = _select(r, params["streams"], params["rename"])
            outs = {p: Output(r.topic_type(t), doc=f"recorded topic {t}")
                    for t, p in ports.items()}
        outs[TIME_JUMP] = Output(int, doc="loop offset (int ns) added to mission time")
        return {}, outs

    def _window(self, r: MissionReader | BagReader) -> tuple[int | None, int | None]:
        info = r.info()
        if info.start_ns is None:
            return None, None
        lo = info.start_ns + int(round(self.start_s * 1e9))
        hi = info.start_ns + int(round(self.end_s * 1e9)) if self.end_s > 0 else None
        if hi is not None and hi <= lo:
            raise ValueError(f"end_s ({self.end_s}) must be after start_s ({self.start_s})")
        return lo, hi

    def start(self) -> None:
        self.reader = open_recording(self.path, run_codecs(self.registry), adapter_params=self.adapter_params)
        self.ports = _select(self.reader, self.streams, self.rename)
        info = self.reader.info()
        if info.truncated:
            self.log.warning("%s", f"{self.path}: truncated recording, replaying the "
                                   f"{info.recovered_count} messages recovered")
        if info.start_ns is not None and info.end_ns is not None \
                and self.start_s * 1e9 > info.end_ns - info.start_ns:  # before anything runs
            raise ValueError(f"{self.path}: start_s {self.start_s} is past the end of the recording "
                             f"({info.duration_s:.3f} s): nothing would be replayed")
        self.replayed = 0
        self.jumps: list[int] = []

    def stop(self) -> None:
        reader = getattr(self, "reader", None)
        if reader is not None:
            reader.close()

    def _downstream(self) -> list[Component]:
        seen: dict[str, Component] = {}
        todo: list[Component] = [self]
        while todo:
            comp = todo.pop()
            for out in comp.outputs.values():
                for inp in out.connected_inputs():
                    if inp.owner.name not in seen and inp.owner is not self:
                        seen[inp.owner.name] = inp.owner
                        todo.append(inp.owner)
        return list(seen.values())

    def generate(self) -> Iterator[tuple[int, str, Any]]:
        r = self.reader
        lo, hi = self._window(r)
        if lo is None:
            return
        offset, first, last, n, k = 0, None, None, 0, 0
        while self.loops == 0 or k < self.loops:
            if k > 0:
                if first is None or last is None:
                    return  # nothing in the window: nothing to loop
                gap = max(1, (last - first) // max(1, n - 1))
                offset += last - first + gap
                self.jumps.append(offset)
                yield first + offset, TIME_JUMP, offset
                for comp in self._downstream():
                    comp.on_time_jump(offset)
            ports = self.ports
            for topic, t, data, _ in r.messages(ports, lo, hi):
                if k == 0:
                    first = t if first is None else first
                    last, n = t, n + 1
                self.replayed += 1
                yield t + offset, ports[topic], data
            k += 1

    def duration_hint_ns(self) -> int | None:
        # asked three times before a run starts (the timer check of the command and of the
        # executor, the progress bar): the recording's summary is read once per file version
        try:
            st = os.stat(self.path)
            key = (self.path, st.st_mtime_ns, st.st_size, self.start_s, self.end_s, self.loops)
        except OSError:
            key = None
        cached = getattr(self, "_hint", None)
        if key is not None and cached is not None and cached[0] == key:
            return cached[1]
        hint = self._duration_hint_ns()
        self._hint = (key, hint)
        return hint

    def _duration_hint_ns(self) -> int | None:
        try:  # the run's registry when built from a graph (no second plugin load)
            with open_recording(self.path, run_codecs(self.registry), adapter_params=self.adapter_params) as r:
                lo, hi = self._window(r)
                end = r.info().end_ns
        except Exception:  # noqa: BLE001 - only a hint
            return None
        if lo is None or end is None:
            return None
        span = (min(hi, end) if hi is not None else end) - lo
        return span * self.loops if self.loops else None

    def losses(self) -> dict[str, int | None]:
        """Output port -> messages lost to damaged chunks (None: an unknown number; ``"?"``:
        the file cannot say which topic)."""
        reader = getattr(self, "reader", None)
        if reader is None:
            return {}
        return {self.ports.get(t, t): n for t, n in reader.lost_counts().items()}

    def summary(self) -> dict[str, Any]:
        out: dict[str, Any] = {"path": self.path, "replayed": getattr(self, "replayed", 0),
                               "loops": len(getattr(self, "jumps", [])) + 1}
        reader = getattr(self, "reader", None)
        if reader is not None:
            skipped = {t: n for t, n in reader.skipped_counts().items() if t not in self.ports}
            if skipped:
                out["skipped"] = skipped  # channels no codec nor adapter reads: messages not replayed
            if reader.late:
                out["late"] = {self.ports.get(t, t): n for t, n in reader.late.items()}
            notes = {self.ports.get(t, t): a.notes() for t, a in reader.adapters().items()}
            notes = {p: n for p, n in notes.items() if n}
            if notes:
                out["adapted"] = notes
        if reader is not None and reader.losses:
            t0 = reader.info().start_ns or 0
            out["lost"] = self.losses()
            out["lost_ranges_s"] = [
                [self.ports.get(loss.topic, loss.topic) if loss.topic else "?",
                 round((loss.start_ns - t0) * 1e-9, 6), round((loss.end_ns - t0) * 1e-9, 6)]
                for loss in reader.losses]
        return out
