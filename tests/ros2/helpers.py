"""Reading back written ROS 2 files with mcap-ros2-support's generic decoder (the schemas stored in the file)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

import impala_msgs
from impala_flow import msgs
from impala_flow.io import CodecRegistry, MissionWriter, run_codecs
from impala_flow.plugins import load_registry


def ros_messages(path: Path) -> dict[str, list[tuple[int, str, Any]]]:
    """topic -> [(log time, schema name, decoded message)] of every CDR channel, in log-time order."""
    out: dict[str, list[tuple[int, str, Any]]] = {}
    factory = DecoderFactory()
    with open(path, "rb") as f:
        for schema, channel, message, decoded in make_reader(f, decoder_factories=[factory]).iter_decoded_messages(
                topics=_cdr_topics(path)):
            out.setdefault(channel.topic, []).append((message.log_time, schema.name, decoded))
    return out


def _cdr_topics(path: Path) -> list[str]:
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return [c.topic for c in summary.channels.values() if c.message_encoding == "cdr"]


def channels(path: Path) -> dict[str, tuple[str, str, str, dict[str, str]]]:
    """topic -> (schema name, schema encoding, message encoding, channel metadata) of every channel."""
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return {c.topic: (summary.schemas[c.schema_id].name, summary.schemas[c.schema_id].encoding, c.message_encoding,
                      dict(c.metadata)) for c in summary.channels.values()}


def ns(stamp: Any) -> int:
    """int ns of a builtin_interfaces/Time."""
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def yaw(q: Any) -> float:
    """Yaw of a quaternion about z (the textbook formula, independent of the writer's)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def cdr_payloads(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    """topic -> [(log time, CDR bytes)] of every CDR channel, in file order."""
    out: dict[str, list[tuple[int, bytes]]] = {}
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(topics=_cdr_topics(path)):
            out.setdefault(channel.topic, []).append((message.log_time, bytes(message.data)))
    return out


T0 = 1_700_000_000_123_456_789  # odd nanoseconds: a stamp that rounds through a float would show it
CONFIG = impala_msgs.RadarConfig("test", 77e9, 1e9, 1e3, 1.0, 4, 0.02, 4.0, 3, 0.5, 100.0)
#: the power of the RadarScan write_every_type writes
SCAN_POWER = np.arange(12, dtype=np.float64).reshape(3, 4) * 1e3 + 0.125


def codecs() -> CodecRegistry:
    """The codecs and foreign writers of the installed plugins (the ros2 one among them)."""
    return run_codecs(load_registry())


def _beam(turn: int, index: int, up: list[float]) -> impala_msgs.RadarBeam:
    return impala_msgs.RadarBeam(0.1 * index, turn, index, np.array(up, dtype=np.float32),
                                 np.zeros(0, dtype=np.float32), CONFIG)


def write_every_type(path: Path) -> Path:
    """A recording of every type the ros2 format writes (and a Speed, which it does not), ROS 2 beside."""
    with MissionWriter(path, codecs=codecs(), foreign=("ros2",)) as w:
        w.add_topic("slam/pose", msgs.Pose2D, "vehicle")
        w.add_topic("gps/pose", msgs.Pose2D)
        w.add_topic("graph/trajectory", msgs.Trajectory2D)
        w.add_topic("odo/twist", msgs.Twist2D)
        w.add_topic("map/prob", msgs.Grid)
        w.add_topic("map/db", msgs.Grid)
        w.add_topic("map/bool", msgs.Grid)
        w.add_topic("radar/detections", impala_msgs.RadarDetections)
        w.add_topic("tracker/tracks", impala_msgs.ObjectStates)
        w.add_topic("radar/scan", impala_msgs.RadarScan)
        w.add_topic("radar/beams", impala_msgs.RadarBeam)
        w.add_topic("odo/speed", impala_msgs.Speed)
        for i, theta in enumerate([0.3, -2.9, 3.1]):
            cov = np.diag([0.01, 0.02, 0.003]) if i else np.zeros((0, 0))
            w.write("slam/pose", T0 + i, msgs.Pose2D(1.5 * i, -2.0, theta, cov, "odom"))
            w.write_transforms(T0 + i, [("odom", "vehicle", 1.5 * i, -2.0, 0.0, theta),
                                        ("vehicle", "radar", 0.5, 0.0, 1.2, 0.0)])
        w.write("gps/pose", T0 + 5, msgs.Pose2D(7.0, 8.0, 0.0))
        w.write("graph/trajectory", T0 + 10, msgs.Trajectory2D(np.array([T0, T0 + 7]),
                                                               np.array([[0.0, 1.0, 0.5], [2.0, 3.0, -0.5]])))
        w.write("odo/twist", T0 + 11, msgs.Twist2D(3.5, -0.25))
        w.write("map/prob", T0 + 12, msgs.Grid(np.array([[0.0, 0.25, 0.5], [1.0, np.nan, 0.994]]), 0.5, 10.0, 20.0))
        w.write("map/db", T0 + 13, msgs.Grid(np.array([[-10.0, 0.0], [30.0, 20.0]]), 2.0, -4.0, 0.0, "map"))
        w.write("map/bool", T0 + 14, msgs.Grid(np.array([[True, False]]), 1.0, 0.0, 0.0))
        w.write("radar/detections", T0 + 15, impala_msgs.RadarDetections(
            4, np.array([T0, T0 + 1]), np.array([3, 9]), np.array([0.25, -1.0]), np.array([12.5, 40.0]),
            np.array([1.5, np.nan]), np.array([7.0, 9.0]), np.array([0.9, np.nan])))
        w.write("tracker/tracks", T0 + 16, impala_msgs.ObjectStates(
            np.array([7, 123456789012]), np.array([[1.0, 2.0], [3.0, 4.0]]), np.array([[0.5, 0.0], [-1.0, 2.0]]),
            np.stack([np.arange(16.0).reshape(4, 4), 2 * np.eye(4)])))
        w.write("radar/scan", T0 + 17, impala_msgs.RadarScan(4, np.array([T0 + 3, T0 + 4, T0 + 5]),
                                                               np.array([0.0, 0.1, 0.2]), SCAN_POWER,
                                                               np.zeros((0, 0)), CONFIG))
        for turn, index, t in [(0, 0, 100), (0, 1, 101), (0, 2, 102), (1, 0, 200), (1, 1, 201), (2, 0, 300)]:
            w.write("radar/beams", T0 + t, _beam(turn, index, [turn, index, 0.5, 1e6]))
        w.write("odo/speed", T0 + 18, impala_msgs.Speed(2.0))
        assert w.foreign_summary()["ros2"]["not written (no ROS 2 message for the type)"] == {"odo/speed": "Speed"}
    return path
