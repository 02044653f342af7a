"""io.Recorder and io.Replayer inside graphs: record, replay, seek, rename, loop, determinism."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

import impala_msgs
from impala_flow import msgs
from impala_flow._clock import FakeClock
from impala_flow._component import Component, Input, Output, Param, Source
from impala_flow._session import Session
from impala_flow.io import MissionReader, MissionWriter
from impala_flow.testing import CollectingSink, plugin_of

from .helpers import assert_same

SEC = 1_000_000_000


class Drive(Source):
    """A scripted mission: poses at 10 Hz, speeds at 20 Hz, an image every second."""

    seconds = Param(int, default=3)
    pose = Output(msgs.Pose2D)
    speed = Output(impala_msgs.Speed)
    image = Output(msgs.Grid)

    def generate(self) -> Iterator[tuple[int, str, Any]]:
        for k in range(self.seconds * 20):
            t = k * SEC // 20
            if k % 2 == 0:
                yield t, "pose", msgs.Pose2D(0.1 * k, -0.2 * k, 0.01 * k, np.eye(3) * k)
            yield t, "speed", impala_msgs.Speed(float(k))
            if k % 20 == 0:
                yield t, "image", msgs.Grid(np.full((8, 8), k, np.float32), 0.5, 0.0, 0.0)


class Jumps(Component):
    """Keeps the speeds it receives and the time jumps announced to it."""

    speed = Input(impala_msgs.Speed)
    start_at = Param(int, default=0)

    def start(self) -> None:
        self.times: list[int] = []
        self.jumps: list[tuple[int, int]] = []

    def process(self, t: int) -> None:
        self.inputs["speed"].take()
        self.times.append(t)

    def on_time_jump(self, offset_ns: int) -> None:
        self.jumps.append((len(self.times), offset_ns))


def session() -> Session:
    return Session(extra_plugins={"test": plugin_of(Drive, Jumps, CollectingSink)})


def record(tmp_path: Path, streams: list[str], name: str = "rec.mcap") -> Path:
    path = tmp_path / name
    text = yaml.safe_dump({
        "name": "drive", "components": {"car": {"type": "test.Drive"}},
        "record": {"path": str(path), "streams": streams, "compression": "lz4"}})
    s = session()
    summary = s.run(s.load_text(text))
    assert summary.extra["record"]["recorded"] > 0
    return path


def replay(path: Path, extra: tuple[str, ...] = (), speed: Any = "max",
           connections: tuple[str, ...] = ("mission.car/speed -> sink.x",)) -> tuple:
    text = yaml.safe_dump({
        "name": "replay", "components": {
            "mission": {"type": "io.Replayer", "params": {"path": str(path)}},
            "sink": {"type": "test.CollectingSink"}},
        "connections": list(connections)})
    s = session()
    spec = s.load_text(text, overrides=list(extra))
    net = s.build(spec)
    summary = s.run(net, speed=speed)
    return summary, net


def test_graph_record_section_records_patterns_with_metadata(tmp_path: Path) -> None:
    path = record(tmp_path, ["car.pose", "car/sp*"])
    with MissionReader(path) as r:
        info = r.info()
        assert set(r.topics) == {"car/pose", "car/speed"}
        poses = [m.data for m in r.messages(["car/pose"])]
    assert info.compression == "lz4" and not info.truncated
    assert len(poses) == 30 and poses[3].x_m == pytest.approx(0.6)
    assert {c.topic for c in info.channels} >= {"/foxglove/car/pose"}
    graph = yaml.safe_load(info.metadata["impala_flow.graph"]["yaml"])
    assert graph["components"]["car"]["type"] == "test.Drive"
    assert "car" in info.metadata["impala_flow.params"]
    assert info.metadata["impala_flow.plugins"]["io"]
    assert info.metadata["impala_flow.streams"] == {"car/pose": "car.pose",
                                                    "car/speed": "car.speed"}


def test_replay_gives_back_the_recorded_samples(tmp_path: Path) -> None:
    path = record(tmp_path, ["car.*"])
    _, net = replay(path, connections=("mission.car/pose -> sink.x",))
    sink = net.components["sink"]
    with MissionReader(path) as r:
        expected = [(m.t_ns, m.data) for m in r.messages(["car/pose"])]
    assert sink.times() == [t for t, _ in expected]
    for a, (_, b) in zip(sink.values(), expected, strict=True):
        assert_same(a, b)
    assert set(net.components["mission"].outputs) == {"car/pose", "car/speed", "car/image",
                                                      "time_jump"}


def test_record_replay_record_is_identical(tmp_path: Path) -> None:
    first = record(tmp_path, ["car.*"], "a.mcap")
    second = tmp_path / "b.mcap"
    text = yaml.safe_dump({
        "name": "again", "components": {
            "mission": {"type": "io.Replayer", "params": {"path": str(first)}}},
        "record": {"path": str(second), "streams": [
            {"from": f"mission.car/{p}", "topic": f"car/{p}"} for p in ("pose", "speed",
                                                                      "image")]}})
    s = session()
    s.run(s.load_text(text))

    def payloads(p: Path) -> list:
        with MissionReader(p) as r:
            return sorted((m.topic, m.t_ns, m.seq, m.data) for m in r.messages(raw=True))

    assert payloads(first) == payloads(second)


def test_max_and_paced_replay_give_identical_outputs(tmp_path: Path) -> None:
    path = record(tmp_path, ["car.*"])
    outs = []
    for clock in (None, FakeClock(1.0)):
        s = session()
        text = yaml.safe_dump({"name": "r", "components": {
            "mission": {"type": "io.Replayer", "params": {"path": str(path)}},
            "sink": {"type": "test.CollectingSink"}},
            "connections": ["mission.car/speed -> sink.x"]})
        net = s.build(s.load_text(text))
        from impala_flow._offline import OfflineExecutor

        OfflineExecutor(net, clock).run()
        sink = net.components["sink"]
        outs.append([(t, v.speed_mps) for t, v in zip(sink.times(), sink.values(),
                                                      strict=True)])
    assert outs[0] == outs[1] and len(outs[0]) == 60


def test_start_end_rename_and_stream_selection(tmp_path: Path) -> None:
    path = record(tmp_path, ["car.*"])
    _, net = replay(path, ("mission.start_s=1.0", "mission.end_s=2.0",
                           "mission.streams=[car/speed]", "mission.rename={car/speed: odo}"),
                    connections=("mission.odo -> sink.x",))
    sink = net.components["sink"]
    assert sink.times() == [SEC + k * SEC // 20 for k in range(20)]
    assert set(net.components["mission"].outputs) == {"odo", "time_jump"}


def test_loop_keeps_mission_time_monotonic_and_announces_the_jump(tmp_path: Path) -> None:
    path = record(tmp_path, ["car.speed"])
    text = yaml.safe_dump({"name": "loop", "components": {
        "mission": {"type": "io.Replayer", "params": {"path": str(path), "loops": 3}},
        "jumps": {"type": "test.Jumps"}, "sink": {"type": "test.CollectingSink"}},
        "connections": ["mission.car/speed -> jumps.speed", "mission.time_jump -> sink.x"]})
    s = session()
    net = s.build(s.load_text(text))
    s.run(net)
    jumps = net.components["jumps"]
    assert len(jumps.times) == 180
    assert all(b > a for a, b in zip(jumps.times, jumps.times[1:], strict=False))
    period = SEC // 20
    span = 59 * period + period
    assert jumps.jumps == [(60, span), (120, 2 * span)]  # after each pass, before the next
    assert net.components["sink"].values() == [span, 2 * span]
    assert jumps.times[60] == jumps.times[59] + period


def test_replayer_reports_bad_files_and_unknown_streams(tmp_path: Path) -> None:
    bad = tmp_path / "bad.mcap"
    bad.write_text("not a recording")
    s = session()
    text = yaml.safe_dump({"name": "r", "components": {
        "mission": {"type": "io.Replayer", "params": {"path": str(bad)}}}})
    with pytest.raises(Exception, match="not an MCAP file"):
        s.load_text(text)
    good = record(tmp_path, ["car.speed"])
    text = yaml.safe_dump({"name": "r", "components": {
        "mission": {"type": "io.Replayer", "params": {"path": str(good),
                                                      "streams": ["lidar/*"]}}}})
    with pytest.raises(Exception, match="matches no recorded topic"):
        session().load_text(text)
    # a window that replays nothing is refused at validation, located at the component
    text = yaml.safe_dump({"name": "r", "components": {
        "mission": {"type": "io.Replayer", "params": {"path": str(good), "start_s": 2.0, "end_s": 1.0}}}})
    with pytest.raises(Exception, match=r"'mission' \(io.Replayer\): end_s 1.0 <= start_s 2.0"):
        session().load_text(text)


def test_replayer_replays_a_truncated_recording(tmp_path: Path) -> None:
    path = tmp_path / "cut.mcap"
    with MissionWriter(path, codecs=__import__("impala_flow.io").io.run_codecs(), chunk_size=1024) as w:
        w.add_topic("car/speed", impala_msgs.Speed)
        for k in range(2000):
            w.write("car/speed", k * 1000, impala_msgs.Speed(float(k)))
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    _, net = replay(path)
    values = [v.speed_mps for v in net.components["sink"].values()]
    assert 0 < len(values) < 2000 and values == [float(k) for k in range(len(values))]
