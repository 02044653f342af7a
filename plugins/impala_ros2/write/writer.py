"""The ROS 2 foreign writer of one recording: streams as standard ROS 2 messages (``ros2msg`` schemas, CDR).

Registered as the output format ``ros2`` (``registry.add_foreign_writer``); the engine's
:class:`~impala_flow.io.MissionWriter` hands it every stream, sample and frame-tree update (see
:mod:`impala_flow.io._foreign`). Topic ``slam/pose`` becomes the ROS topic ``/slam/pose`` (characters
a ROS name cannot hold become ``_``), its path ``/slam/pose/path`` and, when it places a frame on the
frame tree, its odometry ``/slam/pose/odometry``; the frame tree is ``/tf``. The conversions:
:mod:`impala_ros2.write.convert`. Streams of other types are not written (counted by topic in
:meth:`Ros2Writer.summary`).

Bounds: a path holds at most :data:`PATH_MAX_POSES` poses (the newest); a turn gathered from beams at
most :data:`TURN_MAX_BYTES` of power (then written as it is and a new image begun, counted as split).
"""

from __future__ import annotations

import re
from collections import deque
from typing import Any

import numpy as np

import impala_msgs
from impala_flow import msgs
from impala_flow.io import ForeignChannel

from . import convert
from .encode import element, encode, encode_with_elements, encode_with_tail, schema

__all__ = ["Ros2Writer", "ros_topic", "PATH_MAX_POSES", "TURN_MAX_BYTES", "PROFILE"]

PROFILE = "ros2"
PATH_MAX_POSES = 1000
TURN_MAX_BYTES = 64 << 20
#: frame of radar-centred data (detections, B-scans), as the recorder's frame tree names it
RADAR_FRAME = "radar"
VEHICLE_FRAME = "vehicle"
TF_TOPIC = "/tf"


def ros_topic(topic: str) -> str:
    """ROS 2 topic of a stream: ``slam/pose`` -> ``/slam/pose``; characters other than letters, digits, ``_``
    and ``/`` become ``_``."""
    return "/" + re.sub(r"[^A-Za-z0-9_/]", "_", topic.strip("/"))


def _channel(topic: str, ros_type: str) -> ForeignChannel:
    name, data = schema(ros_type)
    return ForeignChannel(topic, name, data, "ros2msg", "cdr")


class _Turn:
    """The beams of one turn gathered for one B-scan (bounded in bytes)."""

    def __init__(self, turn: int, t_ns: int) -> None:
        self.turn, self.t_ns, self.last_ns = turn, t_ns, t_ns
        self.rows: list[np.ndarray] = []
        self.nbytes = 0


class Ros2Writer:
    """Writes the streams of one recording as ROS 2 messages (the ``ros2`` output format)."""

    profile = PROFILE
    frames = True

    def __init__(self) -> None:
        self._out: dict[str, list[ForeignChannel]] = {}
        self._child: dict[str, str] = {}
        self._paths: dict[str, deque] = {}  # topic -> its newest poses, CDR-encoded (encode.element)
        self._turns: dict[str, _Turn] = {}
        self._tf = _channel(TF_TOPIC, "tf2_msgs/TFMessage")
        self._owner: dict[str, str] = {TF_TOPIC: "the frame tree"}  # ROS topic -> the stream written on it
        self.written: dict[str, int] = {}
        self.skipped: dict[str, str] = {}  # topic -> its type, no ROS 2 message for it
        self.split_turns = 0
        self.dropped_beams = 0  # beams whose width differs from their turn's first beam

    # --- declaration -----------------------------------------------------------------------

    def add_topic(self, topic: str, py_type: type, child_frame: str = "") -> list[ForeignChannel]:
        base = ros_topic(topic)
        if py_type is msgs.Pose2D:
            chans = [_channel(base, "geometry_msgs/PoseStamped"), _channel(base + "/path", "nav_msgs/Path")]
            if child_frame:
                chans.append(_channel(base + "/odometry", "nav_msgs/Odometry"))
                self._child[topic] = child_frame
            self._paths[topic] = deque(maxlen=PATH_MAX_POSES)
        elif py_type is msgs.Trajectory2D:
            chans = [_channel(base, "nav_msgs/Path")]
        elif py_type is msgs.Twist2D:
            chans = [_channel(base, "geometry_msgs/TwistStamped")]
        elif py_type is msgs.Grid:
            chans = [_channel(base, "nav_msgs/OccupancyGrid")]
        elif py_type is impala_msgs.RadarDetections:
            chans = [_channel(base, "radar_msgs/RadarScan")]
        elif py_type is impala_msgs.ObjectStates:
            chans = [_channel(base, "radar_msgs/RadarTracks")]
        elif py_type in (impala_msgs.RadarScan, impala_msgs.RadarBeam):
            chans = [_channel(base, "sensor_msgs/Image")]
        else:
            self.skipped[topic] = getattr(py_type, "__name__", str(py_type))
            chans = []
        for ch in chans:
            other = self._owner.setdefault(ch.topic, repr(topic))
            if other != repr(topic):
                raise ValueError(f"ROS 2 topic {ch.topic!r} of stream {topic!r} is already written for "
                                 f"{other}: rename one of the streams")
        self._out[topic] = chans
        return chans

    # --- data ------------------------------------------------------------------------------

    def _msg(self, ch: ForeignChannel, t_ns: int, payload: bytes) -> tuple[ForeignChannel, int, bytes]:
        self.written[ch.topic] = self.written.get(ch.topic, 0) + 1
        return ch, t_ns, payload

    def write(self, topic: str, t_ns: int, value: Any) -> list[tuple[ForeignChannel, int, bytes]]:
        chans = self._out.get(topic)
        if not chans:
            return []
        c = convert
        if isinstance(value, msgs.Pose2D):
            p = value
            ps = c.pose_stamped(t_ns, p.frame, p.x_m, p.y_m, p.theta_rad)
            poses = self._paths[topic]
            poses.append(element("geometry_msgs/PoseStamped", ps))  # each pose encoded once, kept as bytes
            out = [self._msg(chans[0], t_ns, encode(chans[0], ps)),
                   self._msg(chans[1], t_ns, encode_with_elements(chans[1], c.path(t_ns, p.frame, []), list(poses)))]
            if len(chans) > 2:
                od = c.odometry(t_ns, p.frame, self._child[topic], p.x_m, p.y_m, p.theta_rad, p.cov_xyt)
                out.append(self._msg(chans[2], t_ns, encode(chans[2], od)))
            return out
        ch = chans[0]
        if isinstance(value, msgs.Trajectory2D):
            xyt = np.asarray(value.xyt, dtype=np.float64).reshape(-1, 3)
            ts = np.asarray(value.t_ns).reshape(-1).tolist()
            poses = [c.pose_stamped(int(t), value.frame, *row) for t, row in zip(ts, xyt.tolist(), strict=True)]
            return [self._msg(ch, t_ns, encode(ch, c.path(t_ns, value.frame, poses)))]
        if isinstance(value, msgs.Twist2D):
            msg = c.twist_stamped(t_ns, VEHICLE_FRAME, value.speed_mps, value.yaw_rate_radps)
            return [self._msg(ch, t_ns, encode(ch, msg))]
        if isinstance(value, msgs.Grid):
            msg, cells = c.occupancy_grid(t_ns, value.frame, value.data, value.cell_m, value.origin_x_m,
                                          value.origin_y_m)
            return [self._msg(ch, t_ns, encode_with_tail(ch, msg, cells))]
        if isinstance(value, impala_msgs.RadarDetections):
            d = value
            msg = c.radar_scan(t_ns, d.range_m, d.azimuth_rad, d.radial_speed_mps, d.amplitude, RADAR_FRAME)
            return [self._msg(ch, t_ns, encode(ch, msg))]
        if isinstance(value, impala_msgs.ObjectStates):
            o = value
            msg = c.radar_tracks(t_ns, o.frame, o.ids, o.xy_m, o.v_xy_mps, o.cov)
            return [self._msg(ch, t_ns, encode(ch, msg))]
        if isinstance(value, impala_msgs.RadarScan):
            first = int(np.asarray(value.t_ns).reshape(-1)[0]) if np.size(value.t_ns) else t_ns
            return [self._msg(ch, t_ns, encode(ch, c.bscan(first, value.power, RADAR_FRAME)))]
        if isinstance(value, impala_msgs.RadarBeam):
            return self._beam(topic, ch, t_ns, value)
        return []

    def _beam(self, topic: str, ch: ForeignChannel, t_ns: int, b: Any) -> list[tuple[ForeignChannel, int, bytes]]:
        out = []
        turn = self._turns.get(topic)
        row = np.asarray(b.up, dtype="<f4").reshape(-1)
        if turn is not None and (turn.turn != b.turn or turn.nbytes + row.nbytes > TURN_MAX_BYTES):
            if turn.turn == b.turn:
                self.split_turns += 1
            out.append(self._image(ch, turn))
            turn = None
        if turn is None:
            turn = self._turns[topic] = _Turn(b.turn, t_ns)
        if turn.rows and row.shape != turn.rows[0].shape:
            self.dropped_beams += 1
            return out
        turn.rows.append(row)
        turn.nbytes += row.nbytes
        turn.last_ns = t_ns
        return out

    def _image(self, ch: ForeignChannel, turn: _Turn) -> tuple[ForeignChannel, int, bytes]:
        """The B-scan of a gathered turn, logged at its last beam's time, stamped at its first."""
        return self._msg(ch, turn.last_ns, encode(ch, convert.bscan(turn.t_ns, np.stack(turn.rows), RADAR_FRAME)))

    def write_transforms(self, t_ns: int, transforms: list[tuple[str, str, float, float, float, float]]
                         ) -> list[tuple[ForeignChannel, int, bytes]]:
        return [self._msg(self._tf, t_ns, encode(self._tf, convert.tf_message(t_ns, transforms)))]

    def finish(self) -> list[tuple[ForeignChannel, int, bytes]]:
        """The B-scans of the turns still being gathered (the last turn of each beam stream)."""
        out = [self._image(self._out[topic][0], turn) for topic, turn in self._turns.items() if turn.rows]
        self._turns.clear()
        return out

    def summary(self) -> dict[str, Any]:
        out: dict[str, Any] = {"messages": dict(sorted(self.written.items()))}
        if self.skipped:
            out["not written (no ROS 2 message for the type)"] = dict(sorted(self.skipped.items()))
        if self.split_turns:
            out["turns split (over the byte bound)"] = self.split_turns
        if self.dropped_beams:
            out["beams dropped (width differs from their turn's)"] = self.dropped_beams
        return out
