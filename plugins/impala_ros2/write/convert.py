"""The project's types as standard ROS 2 messages (plain dicts, encoded by :mod:`.encode`).

=============== ================================= ==================================================
impala type     ROS 2 message                     how
=============== ================================= ==================================================
Pose2D          geometry_msgs/PoseStamped         yaw -> quaternion (0, 0, sin(yaw/2), cos(yaw/2));
                + nav_msgs/Path (``<topic>/path``) the last poses, bounded; the poses that place a
                + nav_msgs/Odometry               frame on /tf also as Odometry (``<topic>/odometry``,
                                                  child frame = that frame, pose covariance from
                                                  ``cov_xyt`` in x, y, yaw; twist unknown: zeros,
                                                  twist covariance[0] = -1)
Trajectory2D    nav_msgs/Path                     one PoseStamped per row, stamped with its own t_ns
Twist2D         geometry_msgs/TwistStamped        frame ``vehicle``: linear.x = speed, angular.z =
                                                  yaw rate
Grid            nav_msgs/OccupancyGrid            see :func:`occupancy`
RadarDetections radar_msgs/RadarScan              frame ``radar``: range, azimuth, elevation 0, doppler
                                                  = radial speed (NaN: not measured), amplitude
ObjectStates    radar_msgs/RadarTracks            uuid = the id, big-endian in the last 8 bytes;
                                                  position, velocity (z = 0); covariances from
                                                  ``cov`` (x, y, vx, vy), upper triangle xx xy xz yy
                                                  yz zz; classification 0 (none)
RadarScan       sensor_msgs/Image                 one B-scan per turn, see :func:`bscan`
RadarBeam       sensor_msgs/Image                 the beams of one turn gathered into one B-scan
frame tree      tf2_msgs/TFMessage on ``/tf``     one TransformStamped per (parent, child) update
=============== ================================= ==================================================

Every header stamp is the sample's time, exactly: ``sec, nanosec = divmod(t_ns, 10**9)``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["stamp", "header", "quaternion", "pose", "pose_stamped", "path", "odometry", "twist_stamped",
           "occupancy", "occupancy_grid", "radar_scan", "radar_tracks", "bscan", "tf_message"]

#: Image encoding of the B-scans: linear power, float32 (the value every RadarBeam carries)
IMAGE_ENCODING = "32FC1"


def stamp(t_ns: int) -> dict[str, int]:
    """builtin_interfaces/Time of int nanoseconds, exact (sec may be negative, nanosec in [0, 1e9))."""
    sec, nanosec = divmod(int(t_ns), 1_000_000_000)
    if not -(1 << 31) <= sec < (1 << 31):
        raise ValueError(f"time {t_ns} ns does not fit a ROS 2 stamp (int32 seconds)")
    return {"sec": sec, "nanosec": nanosec}


def header(t_ns: int, frame: str) -> dict[str, Any]:
    return {"stamp": stamp(t_ns), "frame_id": frame}


def quaternion(yaw_rad: float) -> dict[str, float]:
    """Rotation by ``yaw_rad`` about z."""
    h = 0.5 * float(yaw_rad)
    return {"x": 0.0, "y": 0.0, "z": math.sin(h), "w": math.cos(h)}


def pose(x_m: float, y_m: float, yaw_rad: float, z_m: float = 0.0) -> dict[str, Any]:
    return {"position": {"x": float(x_m), "y": float(y_m), "z": float(z_m)}, "orientation": quaternion(yaw_rad)}


def pose_stamped(t_ns: int, frame: str, x_m: float, y_m: float, yaw_rad: float) -> dict[str, Any]:
    return {"header": header(t_ns, frame), "pose": pose(x_m, y_m, yaw_rad)}


def path(t_ns: int, frame: str, poses: list[dict[str, Any]]) -> dict[str, Any]:
    """nav_msgs/Path of PoseStamped dicts."""
    return {"header": header(t_ns, frame), "poses": poses}


def _cov6(cov_xyt: np.ndarray) -> list[float]:
    """The 6 x 6 (x, y, z, roll, pitch, yaw) covariance of a 3 x 3 over (x, y, yaw), row-major; zeros when
    ``cov_xyt`` is empty (ROS: unknown covariance)."""
    out = np.zeros((6, 6))
    c = np.asarray(cov_xyt, dtype=np.float64)
    if c.shape == (3, 3):
        idx = [0, 1, 5]
        out[np.ix_(idx, idx)] = c
    return out.reshape(-1).tolist()


def odometry(t_ns: int, frame: str, child: str, x_m: float, y_m: float, yaw_rad: float,
             cov_xyt: np.ndarray) -> dict[str, Any]:
    """nav_msgs/Odometry of a pose; its twist is not known (zeros, twist covariance[0] = -1)."""
    unknown = [0.0] * 36
    unknown[0] = -1.0
    return {"header": header(t_ns, frame), "child_frame_id": child,
            "pose": {"pose": pose(x_m, y_m, yaw_rad), "covariance": _cov6(cov_xyt)},
            "twist": {"twist": {"linear": {"x": 0.0, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}},
                      "covariance": unknown}}


def twist_stamped(t_ns: int, frame: str, speed_mps: float, yaw_rate_radps: float) -> dict[str, Any]:
    return {"header": header(t_ns, frame),
            "twist": {"linear": {"x": float(speed_mps), "y": 0.0, "z": 0.0},
                      "angular": {"x": 0.0, "y": 0.0, "z": float(yaw_rate_radps)}}}


def occupancy(data: np.ndarray) -> np.ndarray:
    """int8 cells of nav_msgs/OccupancyGrid (0..100, -1 unknown) from a Grid's values:

    - NaN cells are -1 (unknown);
    - a boolean grid is 0 / 100;
    - a grid whose values all lie in [0, 1] (probabilities) is ``round(100 v)``;
    - any other grid is scaled linearly from its own minimum (0) to its maximum (100),
      ``round(100 (v - min) / (max - min))`` (a constant grid: 0); +-inf count as the extremes.
    """
    a = np.asarray(data)
    if a.dtype.kind == "b":
        return np.where(a, 100, 0).astype(np.int8)
    v = np.abs(a) if a.dtype.kind == "c" else a
    v = v.astype(np.float64)
    known = ~np.isnan(v)
    out = np.full(v.shape, -1, dtype=np.int8)
    if not known.any():
        return out
    vals = v[known]
    lo, hi = float(vals.min()), float(vals.max())
    if lo >= 0.0 and hi <= 1.0:
        out[known] = np.rint(100.0 * vals).astype(np.int8)
        return out
    finite = vals[np.isfinite(vals)]
    flo, fhi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 0.0)
    clipped = np.clip(vals, flo, fhi)
    span = fhi - flo
    out[known] = (np.rint(100.0 * (clipped - flo) / span) if span > 0 else np.zeros(vals.shape)).astype(np.int8)
    return out


def occupancy_grid(t_ns: int, frame: str, data: np.ndarray, cell_m: float, origin_x_m: float,
                   origin_y_m: float) -> tuple[dict[str, Any], bytes]:
    """nav_msgs/OccupancyGrid without its ``data`` (returned apart, as raw int8 bytes: rows = y, columns = x,
    the layout of a Grid). ``info.origin`` is the corner of cell (0, 0), half a cell before its centre."""
    cells = occupancy(data)
    rows, cols = cells.shape
    half = 0.5 * float(cell_m)
    msg = {"header": header(t_ns, frame),
           "info": {"map_load_time": stamp(t_ns), "resolution": float(cell_m), "width": cols, "height": rows,
                    "origin": pose(float(origin_x_m) - half, float(origin_y_m) - half, 0.0)},
           "data": []}
    return msg, np.ascontiguousarray(cells).tobytes()


def radar_scan(t_ns: int, range_m: np.ndarray, azimuth_rad: np.ndarray, radial_speed_mps: np.ndarray,
               amplitude: np.ndarray, frame: str = "radar") -> dict[str, Any]:
    """radar_msgs/RadarScan: one RadarReturn per detection (float32 fields)."""
    cols = [np.asarray(c, dtype=np.float64).reshape(-1).tolist() for c in
            (range_m, azimuth_rad, radial_speed_mps, amplitude)]
    returns = [{"range": r, "azimuth": az, "elevation": 0.0, "doppler_velocity": v, "amplitude": amp}
               for r, az, v, amp in zip(*cols, strict=True)]
    return {"header": header(t_ns, frame), "returns": returns}


def _upper(c: np.ndarray) -> list[float]:
    """float32[6] covariance (xx, xy, xz, yy, yz, zz) of a 2 x 2 planar one."""
    return [float(c[0, 0]), float(c[0, 1]), 0.0, float(c[1, 1]), 0.0, 0.0]


def uuid(track_id: int) -> bytes:
    """16 bytes naming a track: its id as a big-endian int64 in the last 8 bytes."""
    return bytes(8) + int(track_id).to_bytes(8, "big", signed=True)


def radar_tracks(t_ns: int, frame: str, ids: np.ndarray, xy_m: np.ndarray, v_xy_mps: np.ndarray,
                 cov: np.ndarray) -> dict[str, Any]:
    """radar_msgs/RadarTracks of object states (planar: z = 0, size and acceleration unknown: zeros)."""
    xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
    v = np.asarray(v_xy_mps, dtype=np.float64).reshape(-1, 2)
    c = np.asarray(cov, dtype=np.float64)
    has_cov = c.shape == (len(xy), 4, 4) and len(xy) > 0
    zero3 = {"x": 0.0, "y": 0.0, "z": 0.0}
    tracks = []
    for i, oid in enumerate(np.asarray(ids).reshape(-1).tolist()):
        tracks.append({
            "uuid": {"uuid": uuid(oid)},
            "position": {"x": float(xy[i, 0]), "y": float(xy[i, 1]), "z": 0.0},
            "velocity": {"x": float(v[i, 0]), "y": float(v[i, 1]), "z": 0.0},
            "acceleration": zero3, "size": zero3, "classification": 0,
            "position_covariance": _upper(c[i, :2, :2]) if has_cov else [0.0] * 6,
            "velocity_covariance": _upper(c[i, 2:, 2:]) if has_cov else [0.0] * 6,
            "acceleration_covariance": [0.0] * 6, "size_covariance": [0.0] * 6})
    return {"header": header(t_ns, frame), "tracks": tracks}


def bscan(t_ns: int, power: np.ndarray, frame: str = "radar") -> dict[str, Any]:
    """sensor_msgs/Image of one turn: height = beams (azimuths, in acquisition order), width = range bins,
    ``32FC1`` little-endian linear power (the value the chain works on, to float32: no per-turn scale to
    undo), stamped at the turn's first beam (as Navtech's ROS 2 driver does)."""
    img = np.ascontiguousarray(np.asarray(power), dtype="<f4")
    if img.ndim != 2:
        raise ValueError(f"a B-scan is 2-D (beams x bins), got shape {img.shape}")
    rows, cols = img.shape
    return {"header": header(t_ns, frame), "height": rows, "width": cols, "encoding": IMAGE_ENCODING,
            "is_bigendian": 0, "step": 4 * cols, "data": img.tobytes()}


def tf_message(t_ns: int, transforms: list[tuple[str, str, float, float, float, float]]) -> dict[str, Any]:
    """tf2_msgs/TFMessage of planar transforms (parent, child, x_m, y_m, z_m, yaw_rad)."""
    return {"transforms": [
        {"header": header(t_ns, parent), "child_frame_id": child,
         "transform": {"translation": {"x": float(x), "y": float(y), "z": float(z)}, "rotation": quaternion(yaw)}}
        for parent, child, x, y, z, yaw in transforms]}
