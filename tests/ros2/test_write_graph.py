"""ROS 2 output of a graph's recording (``record: {ros2: beside|only}``) and of ``impala-flow export --ros2``:
dead reckoning from an odometer and a gyro replayed through a graph, and a simulated radar mission; the ROS 2
messages decoded with the generic decoder against the native samples of the same run."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader

import impala_msgs
from impala_flow import Session
from impala_flow.cli import main
from impala_flow.io import MissionReader, MissionWriter, run_codecs
from impala_flow.plugins import DISABLE_ENV

from .helpers import cdr_payloads, channels, ns, ros_messages, yaw

T0 = 1_767_225_600_000_000_007


def _odometry_mission(path: Path) -> Path:
    """20 s of an odometer (2 m/s) and a gyro (0.1 rad/s) at 10 Hz, odd nanoseconds."""
    with MissionWriter(path, codecs=run_codecs()) as w:
        w.add_topic("odo/speed", impala_msgs.Speed)
        w.add_topic("gyro/yaw_rate", impala_msgs.YawRate)
        for i in range(200):
            w.write("odo/speed", T0 + i * 100_000_003, impala_msgs.Speed(2.0), i)
            w.write("gyro/yaw_rate", T0 + i * 100_000_003, impala_msgs.YawRate(0.1), i)
    return path


def _run(tmp_path: Path, ros2: str) -> tuple[Path, dict]:
    mission = _odometry_mission(tmp_path / "m.mcap")
    graph = tmp_path / f"dr_{ros2}.yaml"
    graph.write_text(yaml.safe_dump({
        "name": "dr", "clock": {"mode": "replay", "speed": "max"},
        "components": {"mission": {"type": "io.Replayer", "params": {"path": str(mission)}},
                       "deadreckoning": {"type": "slam.DeadReckoning", "params": {"period_s": 0.5}}},
        "connections": ["mission.odo/speed -> deadreckoning.odometer", "mission.gyro/yaw_rate -> deadreckoning.gyro"],
        "record": {"path": f"out_{ros2}.mcap", "streams": ["deadreckoning.pose"], "ros2": ros2}}))
    session = Session()
    summary = session.run(session.build(session.load(graph)))
    return tmp_path / f"out_{ros2}.mcap", summary.extra["record"]


def test_a_graph_records_its_poses_beside_as_ros2_messages_equal_to_the_native_ones(tmp_path: Path) -> None:
    out, summary = _run(tmp_path, "beside")
    with MissionReader(out) as r:
        assert list(r.topics) == ["deadreckoning/pose"]
        native = list(r.messages())
    assert len(native) > 30
    ros = ros_messages(out)
    poses = ros["/deadreckoning/pose"]
    assert len(poses) == len(native)
    for (t, schema, m), s in zip(poses, native, strict=True):
        assert schema == "geometry_msgs/msg/PoseStamped"
        assert t == s.t_ns == ns(m.header.stamp)  # stamps exact
        assert m.header.frame_id == s.data.frame == "odom"
        assert (m.pose.position.x, m.pose.position.y) == (s.data.x_m, s.data.y_m)
        assert yaw(m.pose.orientation) == pytest.approx(s.data.theta_rad, abs=1e-12)
    last_path = ros["/deadreckoning/pose/path"][-1][2]
    assert [ns(p.header.stamp) for p in last_path.poses] == [s.t_ns for s in native]
    odo = [m for _, _, m in ros["/deadreckoning/pose/odometry"]]
    assert {o.child_frame_id for o in odo} == {"vehicle"}  # deadreckoning/pose places the vehicle
    tf = [m for _, _, m in ros["/tf"]]
    assert len(tf) == len(native)
    assert [(x.header.frame_id, x.child_frame_id) for x in tf[0].transforms] == [("odom", "vehicle"),
                                                                                ("vehicle", "radar")]
    assert summary["ros2"] == {"messages": {t: len(v) for t, v in ros.items()}}  # the run summary says it
    ch = channels(out)
    assert ch["/tf"][0] == "tf2_msgs/msg/TFMessage"  # ROS 2's /tf replaces the Foxglove frame tree
    assert "/foxglove/deadreckoning/pose" in ch  # the other Foxglove mirrors stay


def test_a_graph_records_only_ros2_a_file_ros2_bag_play_reads(tmp_path: Path) -> None:
    out, _ = _run(tmp_path, "only")
    with open(out, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
    assert summary is not None
    assert {(s.encoding) for s in summary.schemas.values()} == {"ros2msg"}
    assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
    beside, _ = _run(tmp_path, "beside")
    assert cdr_payloads(out) == cdr_payloads(beside)  # the same ROS 2 messages, byte for byte
    assert len(ros_messages(out)["/deadreckoning/pose"]) > 30


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    mission = tmp_path_factory.mktemp("sim") / "beynes.mcap"
    assert main(["simulate", "beynes", "-o", str(mission), "--duration", "2s", "--no-progress"]) == 0
    return mission


def test_export_ros2_of_a_radar_mission_bscans_per_turn_and_poses(simulated: Path, tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "ros2.mcap"
    assert main(["export", str(simulated), "--ros2", str(out)]) == 0
    err = capsys.readouterr().err
    with MissionReader(simulated) as r:
        beams = list(r.messages(["radar/beams"]))
        gps = list(r.messages(["gps/pose"]))
        n = sum(1 for _ in r.messages())
    turns: dict[int, list] = defaultdict(list)
    for b in beams:
        turns[b.data.turn].append(b)
    ros = ros_messages(out)
    images = ros["/radar/beams"]
    assert len(images) == len(turns) >= 2
    for (t, schema, img), (_, turn) in zip(images, sorted(turns.items()), strict=True):
        assert schema == "sensor_msgs/msg/Image" and img.encoding == "32FC1"
        assert ns(img.header.stamp) == turn[0].t_ns and t == turn[-1].t_ns  # stamped at its first azimuth
        assert (img.height, img.width) == (len(turn), len(turn[0].data.up))
        rows = np.frombuffer(bytes(img.data), dtype="<f4").reshape(img.height, img.width)
        assert np.array_equal(rows, np.stack([b.data.up for b in turn]).astype(np.float32))
    poses = ros["/gps/pose"]
    assert [(ns(m.header.stamp), m.pose.position.x, m.pose.position.y) for _, _, m in poses] == [
        (s.t_ns, s.data.x_m, s.data.y_m) for s in gps]
    assert {m.child_frame_id for _, _, m in ros["/gps/pose/odometry"]} == {"vehicle"}
    assert f"{out}: {sum(len(v) for v in ros.values())} ROS 2 messages from {n} samples" in err
    assert "not written (no ROS 2 message for the type)" in err  # odometer, gyro: said, not silently left
    with open(out, "rb") as f:
        assert make_reader(f).get_header().profile == "ros2"


def test_export_ros2_native_keeps_the_recording_readable_and_topic_restricts(simulated: Path, tmp_path: Path) -> None:
    out = tmp_path / "both.mcap"
    assert main(["export", str(simulated), "--ros2", str(out), "--native", "--topic", "gps/pose"]) == 0
    with MissionReader(simulated) as a, MissionReader(out) as b:
        assert list(b.topics) == ["gps/pose"]
        assert [(m.t_ns, m.data.x_m) for m in b.messages()] == [(m.t_ns, m.data.x_m) for m in a.messages(["gps/pose"])]
    assert sorted(t for t, c in channels(out).items() if c[2] == "cdr") == [
        "/gps/pose", "/gps/pose/odometry", "/gps/pose/path", "/tf"]


def test_export_ros2_usage_and_missing_plugin_are_one_line(simulated: Path, tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str],
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    def error(argv: list[str], code: int) -> str:
        assert main(argv) == code
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1, lines
        return lines[0].split(": error: ", 1)[1]

    out = str(tmp_path / "o.mcap")
    assert error(["export", str(simulated), "--ros2", out, "--csv"], 2) == (
        "export: give one output format, --csv (with --topic) or --ros2 OUT.mcap")
    assert error(["export", str(simulated)], 2) == "export: give one output format, --csv (with --topic) or --ros2 " \
                                                   "OUT.mcap"
    assert error(["export", str(simulated), "--ros2", str(simulated)], 2).startswith("--ros2: ")
    assert error(["export", str(simulated), "--ros2", out, "--topic", "nope"], 2).startswith(
        f"{simulated}: no topic 'nope'")
    monkeypatch.setenv(DISABLE_ENV, "ros2")
    assert error(["export", str(simulated), "--ros2", out], 1) == (
        "export --ros2: ros2 output unavailable: no plugin registers it (the 'ros2' plugin: "
        "pip install 'impala-flow[ros2]')")
    assert not Path(out).exists()


def test_export_ros2_of_a_damaged_recording_fails_unless_allow_loss_then_writes_every_readable_pose(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from impala_flow import msgs

    path = tmp_path / "m.mcap"
    with MissionWriter(path, codecs=run_codecs(), chunk_size=4096) as w:
        w.add_topic("gps/pose", msgs.Pose2D)
        for i in range(600):
            w.write("gps/pose", T0 + i * 1_000_000, msgs.Pose2D(float(i), 0.0, 0.0), i)
    with open(path, "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    bad = chunks[2]
    data = bytearray(path.read_bytes())
    data[bad.chunk_start_offset + bad.chunk_length - 30] ^= 0x10  # a flipped bit inside chunk 2
    path.write_bytes(bytes(data))
    out = tmp_path / "r.mcap"
    assert main(["export", str(path), "--ros2", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert "of 'gps/pose' lost in damaged chunks" in err and "nothing written" in err and not out.exists()
    assert main(["export", str(path), "--ros2", str(out), "--allow-loss"]) == 0
    err = capsys.readouterr().err
    assert "lost in damaged chunks" in err
    with MissionReader(path) as r:
        readable = [(m.t_ns, m.data.x_m) for m in r.messages()]
    assert 0 < len(readable) < 600
    assert [(ns(m.header.stamp), m.pose.position.x) for _, _, m in ros_messages(out)["/gps/pose"]] == readable


def test_a_graph_asking_for_ros2_without_the_plugin_is_refused_before_it_runs(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    mission = _odometry_mission(tmp_path / "m.mcap")
    graph = tmp_path / "g.yaml"
    graph.write_text(yaml.safe_dump({
        "components": {"mission": {"type": "io.Replayer", "params": {"path": str(mission)}},
                       "deadreckoning": {"type": "slam.DeadReckoning"}},
        "connections": ["mission.odo/speed -> deadreckoning.odometer", "mission.gyro/yaw_rate -> deadreckoning.gyro"],
        "record": {"path": "out.mcap", "streams": ["deadreckoning.pose"], "ros2": "only"}}))
    assert main(["validate", str(graph)]) == 0
    capsys.readouterr()
    monkeypatch.setenv(DISABLE_ENV, "ros2")
    for command in ("validate", "run"):
        assert main([command, str(graph), "--no-progress"] if command == "run" else [command, str(graph)]) == 2
        err = capsys.readouterr().err
        assert err.strip().splitlines()[-1].endswith(
            "record: 'ros2': ros2 output unavailable: no plugin registers it (the 'ros2' plugin: "
            "pip install 'impala-flow[ros2]')"), err
    assert not (tmp_path / "out.mcap").exists()
