"""Poses, motion, GPS and detections from ROS 2 messages.

=============================== ============================== ==================================================
ROS 2 type                      sample                         how
=============================== ============================== ==================================================
nav_msgs/Odometry               Pose2D (frame header.frame_id) x, y of the pose; theta = yaw of its quaternion
geometry_msgs/PoseStamped       Pose2D                         same
geometry_msgs/TransformStamped  Pose2D                         the child frame in header.frame_id
sensor_msgs/Imu                 YawRate                        angular_velocity.z (rad/s, counter-clockwise)
sensor_msgs/NavSatFix           Pose2D (frame "enu")           local east-north of the first fix (below)
geometry_msgs/TwistStamped      Twist2D                        speed = linear.x, yaw rate = angular.z
radar_msgs/RadarScan            RadarDetections                range, azimuth (REP-103: counter-clockwise, the
                                                               project's), doppler_velocity, amplitude dB -> linear
=============================== ============================== ==================================================

Every sample is stamped with its header's stamp (sec * 10^9 + nanosec, exact; the log time when it is zero).
NavSatFix: fixes without a fix (status -1) are dropped and counted; the first valid fix is the origin, and a fix is
placed with the equirectangular (local tangent) formula on the WGS-84 ellipsoid at the origin's latitude:
east = (N + h0) cos(lat0) dlon, north = (M + h0) dlat, with M and N the meridional and prime-vertical radii of
curvature. Its error against the exact local ENU grows as d^2 / (2 R) with the distance d from the origin (under
1 mm within 100 m, about 8 cm at 1 km); theta is 0 with a variance of pi^2 / 3 (heading unknown), x/y variances from
the fix's covariance when it has one.
"""

from __future__ import annotations

import math

import numpy as np

import impala_msgs
from impala_flow import msgs
from impala_flow.io import AdaptedChannel, AdapterContext

from .cdr import decoder_of, stamp_ns, yaw_of
from .params import check_params

__all__ = ["PoseAdapter", "ImuAdapter", "NavSatAdapter", "TwistAdapter", "RadarScanAdapter", "enu_of"]

WGS84_A_M = 6_378_137.0
WGS84_E2 = 6.694379990141317e-3


def enu_of(lat_deg: float, lon_deg: float, lat0_deg: float, lon0_deg: float, h0_m: float = 0.0) -> tuple[float, float]:
    """(east, north) in metres of a fix from the origin fix, equirectangular on the WGS-84 ellipsoid."""
    phi0 = math.radians(lat0_deg)
    w = math.sqrt(1.0 - WGS84_E2 * math.sin(phi0) ** 2)
    n = WGS84_A_M / w  # prime vertical radius of curvature
    m = WGS84_A_M * (1.0 - WGS84_E2) / w**3  # meridional radius of curvature
    dlon = math.radians((lon_deg - lon0_deg + 180.0) % 360.0 - 180.0)
    return (n + h0_m) * math.cos(phi0) * dlon, (m + h0_m) * math.radians(lat_deg - lat0_deg)


class _Adapter:
    value_type: type = msgs.Pose2D

    def __init__(self, channel: AdaptedChannel, context: AdapterContext) -> None:
        check_params(context.params)
        self.channel = channel
        self.decode = decoder_of(channel)
        self.dropped = 0

    def notes(self) -> list[str]:
        return []


class PoseAdapter(_Adapter):
    """Odometry, PoseStamped, TransformStamped -> Pose2D in the header's frame."""

    def adapt(self, payload: memoryview, log_time_ns: int) -> list[tuple[int, msgs.Pose2D]]:
        m = self.decode(payload)
        if hasattr(m, "transform"):
            p, q = m.transform.translation, m.transform.rotation
        else:
            pose = m.pose.pose if hasattr(m.pose, "pose") else m.pose
            p, q = pose.position, pose.orientation
        frame = str(m.header.frame_id) or "map"
        return [(stamp_ns(m.header, log_time_ns), msgs.Pose2D(float(p.x), float(p.y), yaw_of(q), frame=frame))]


class ImuAdapter(_Adapter):
    value_type = impala_msgs.YawRate

    def adapt(self, payload: memoryview, log_time_ns: int) -> list[tuple[int, impala_msgs.YawRate]]:
        m = self.decode(payload)
        return [(stamp_ns(m.header, log_time_ns), impala_msgs.YawRate(float(m.angular_velocity.z)))]


class TwistAdapter(_Adapter):
    value_type = msgs.Twist2D

    def adapt(self, payload: memoryview, log_time_ns: int) -> list[tuple[int, msgs.Twist2D]]:
        m = self.decode(payload)
        return [(stamp_ns(m.header, log_time_ns), msgs.Twist2D(float(m.twist.linear.x), float(m.twist.angular.z)))]


class NavSatAdapter(_Adapter):
    """NavSatFix -> Pose2D (frame ``enu``) from the first valid fix."""

    def __init__(self, channel: AdaptedChannel, context: AdapterContext) -> None:
        super().__init__(channel, context)
        self.origin: tuple[float, float, float] | None = None

    def notes(self) -> list[str]:
        out = []
        if self.origin is not None:
            out.append(f"positions: local east-north from the first fix ({self.origin[0]:.7f}, {self.origin[1]:.7f}), "
                       "equirectangular on WGS-84 (error ~ d^2/2R: 8 cm at 1 km)")
        if self.dropped:
            out.append(f"{self.dropped} fix(es) without a fix (status -1) or not finite: dropped")
        return out

    def adapt(self, payload: memoryview, log_time_ns: int) -> list[tuple[int, msgs.Pose2D]]:
        m = self.decode(payload)
        lat, lon, alt = float(m.latitude), float(m.longitude), float(m.altitude)
        if int(m.status.status) < 0 or not (math.isfinite(lat) and math.isfinite(lon)) or abs(lat) > 90.0:
            self.dropped += 1
            return []
        if self.origin is None:
            self.origin = (lat, lon, alt if math.isfinite(alt) else 0.0)
        x, y = enu_of(lat, lon, self.origin[0], self.origin[1], self.origin[2])
        cov = np.diag([1.0, 1.0, msgs.HEADING_UNKNOWN_VAR_RAD2])
        c = np.asarray(m.position_covariance, dtype=np.float64)
        if int(m.position_covariance_type) > 0 and c.size == 9 and np.isfinite(c).all():
            cov[:2, :2] = c.reshape(3, 3)[:2, :2]
        return [(stamp_ns(m.header, log_time_ns), msgs.Pose2D(x, y, 0.0, cov, frame="enu"))]


class RadarScanAdapter(_Adapter):
    """radar_msgs/RadarScan -> RadarDetections (one per message; turn = message count)."""

    value_type = impala_msgs.RadarDetections

    def __init__(self, channel: AdaptedChannel, context: AdapterContext) -> None:
        super().__init__(channel, context)
        self.turn = -1

    def adapt(self, payload: memoryview, log_time_ns: int) -> list[tuple[int, impala_msgs.RadarDetections]]:
        m = self.decode(payload)
        t = stamp_ns(m.header, log_time_ns)
        r = m.returns
        n = len(r)
        col = np.array([[x.range, x.azimuth, x.doppler_velocity, x.amplitude] for x in r],
                       dtype=np.float64).reshape(n, 4)
        if not np.isfinite(col).all():
            raise ValueError("a return with a non-finite range, azimuth, doppler or amplitude")
        self.turn += 1
        return [(t, impala_msgs.RadarDetections(
            self.turn, np.full(n, t, dtype=np.int64), np.arange(n, dtype=np.int64), msgs.wrap_angle(col[:, 1]),
            col[:, 0], col[:, 2], np.power(10.0, col[:, 3] / 10.0), np.full(n, np.nan)))]
