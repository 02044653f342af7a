"""Reader for Navtech spinning-radar polar PNGs (Oxford Radar RobotCar, MulRan, Boreas).

File format (one PNG per antenna turn, 8-bit grey, one row per azimuth):
columns 0-7 little-endian int64 timestamp (us), columns 8-9 little-endian uint16 encoder
count (``encoder_size`` = 5600 counts per turn), column 10 valid flag (255 = valid),
columns 11... power per range bin (value / 255; Navtech stores it log-compressed).

Conventions (checked against the dataset's GPS in the tests):

* Navtech azimuths (``NavtechScan.azimuth_rad`` = count / 5600 * 2 pi) turn **clockwise**
  seen from above, 0 = vehicle forward (the Oxford SDK's Cartesian projection).
  :func:`scan_to_beams` converts to the project's ``RadarBeam.azimuth_rad``:
  counter-clockwise, 0 = heading, i.e. ``wrap(-azimuth)``.
* Oxford ground truth (``gt/radar_odometry.csv``) uses x forward, y **right**, yaw
  **clockwise** (z down). Each row is the pose of the *source* (later) scan in the frame
  of the *destination* (earlier) scan: ``T_abs(source) = T_abs(destination) (+) T_row``
  (the SDK's ``abs_pose = abs_poses[-1] * rel_pose``). :func:`read_oxford_ground_truth`
  returns it in the project's frame (x forward, y left, yaw counter-clockwise): y and yaw
  negated. The row's ``source_timestamp`` is the middle of the source scan; the truth
  poses are stamped there.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from impala_flow import msgs

__all__ = [
    "NAVTECH_CTS350X", "NavtechScan", "OxfordRelativePoses", "read_navtech_png",
    "scan_to_beams", "read_oxford_ground_truth", "compose_relative_poses",
    "iter_oxford_folder",
]

_RANGE_BIN_M = 0.0432
_BANDWIDTH_HZ = 1.0e9  # 76-77 GHz sweep
_SWEEPS_HZ = 1600.0  # 400 azimuths x 4 turns/s, one sweep per azimuth

NAVTECH_CTS350X = msgs.RadarConfig(
    name="navtech-cts350x",
    f0_hz=76.5e9,
    bandwidth_hz=_BANDWIDTH_HZ,
    modulation_hz=_SWEEPS_HZ,
    # range_per_bin_m = c bin_hz / (4 dF Fm) = 0.0432 m
    bin_hz=_RANGE_BIN_M * 4.0 * _BANDWIDTH_HZ * _SWEEPS_HZ / msgs.SPEED_OF_LIGHT_MPS,
    n_bins=3768,
    beam_width_rad=math.radians(1.8),
    rotation_hz=4.0,
    beams_per_turn=400,
    range_min_m=0.0,
    range_max_m=3768 * _RANGE_BIN_M,
    doppler=False,
)
"""Navtech CTS350-X as in Oxford Radar RobotCar: 4 Hz, 400 beams, 3768 bins of 4.32 cm."""


@dataclass(eq=False)
class NavtechScan:
    """One decoded turn: per-azimuth ``timestamps_ns`` (int64), ``encoder`` counts,
    ``azimuth_rad`` (clockwise, see module doc), ``valid`` (bool) and ``power`` (float32,
    azimuths x range bins, in [0, 1])."""

    timestamps_ns: np.ndarray
    encoder: np.ndarray
    azimuth_rad: np.ndarray
    valid: np.ndarray
    power: np.ndarray


def read_navtech_png(path: str | Path, encoder_size: int = 5600,
                     timestamp_unit_ns: int = 1000) -> NavtechScan:
    """Decode one Navtech polar PNG (see the module doc for the layout)."""
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise FileNotFoundError(f"cannot read Navtech PNG {path}")
    if img.ndim != 2 or img.dtype != np.uint8 or img.shape[1] <= 11:
        raise ValueError(f"{path}: not a Navtech polar PNG (shape {img.shape}, {img.dtype})")
    stamps = np.ascontiguousarray(img[:, :8]).view("<i8")[:, 0].astype(np.int64)
    encoder = np.ascontiguousarray(img[:, 8:10]).view("<u2")[:, 0]
    return NavtechScan(
        timestamps_ns=stamps * timestamp_unit_ns,
        encoder=encoder,
        azimuth_rad=encoder.astype(np.float64) * (2.0 * np.pi / encoder_size),
        valid=img[:, 10] == 255,
        power=img[:, 11:].astype(np.float32) / np.float32(255.0),
    )


def scan_to_beams(scan: NavtechScan, turn: int,
                  config: msgs.RadarConfig = NAVTECH_CTS350X) -> list[tuple[int, msgs.RadarBeam]]:
    """Valid rows of ``scan`` as ``(t_ns, RadarBeam)`` (power in ``up``, ``down`` empty),
    azimuth converted to counter-clockwise from the heading."""
    empty = np.zeros(0, dtype=np.float32)
    azimuth_ccw = msgs.wrap_angle(-scan.azimuth_rad)
    beams = []
    for i in np.flatnonzero(scan.valid).tolist():
        beam = msgs.RadarBeam(float(azimuth_ccw[i]), int(turn), i, scan.power[i], empty, config)
        beams.append((int(scan.timestamps_ns[i]), beam))
    return beams


@dataclass(eq=False)
class OxfordRelativePoses:
    """Rows of ``radar_odometry.csv`` in the project frame (x forward, y left, yaw CCW):
    pose of the source scan in the destination scan's frame. Timestamps in ns: the
    pose times (``source_t_ns``: middle of the scan) and the scans' own (file) times."""

    source_t_ns: np.ndarray
    destination_t_ns: np.ndarray
    source_radar_t_ns: np.ndarray
    destination_radar_t_ns: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    yaw_rad: np.ndarray

    def select(self, mask: np.ndarray) -> OxfordRelativePoses:
        return OxfordRelativePoses(*(getattr(self, f)[mask] for f in self.__dataclass_fields__))


def read_oxford_ground_truth(csv_path: str | Path) -> OxfordRelativePoses:
    """Read an Oxford ``radar_odometry.csv``; y and yaw negated into the project frame."""
    cols = ["source_timestamp", "destination_timestamp", "x", "y", "yaw",
            "source_radar_timestamp", "destination_radar_timestamp"]
    with open(csv_path) as f:
        header = f.readline().strip().split(",")
    missing = [c for c in cols if c not in header]
    if missing:
        raise ValueError(f"{csv_path}: missing column(s) {', '.join(missing)}")
    idx = [header.index(c) for c in cols]
    ints = np.loadtxt(csv_path, delimiter=",", skiprows=1, usecols=[idx[i] for i in (0, 1, 5, 6)],
                      dtype=np.int64, ndmin=2)
    xyy = np.loadtxt(csv_path, delimiter=",", skiprows=1, usecols=idx[2:5], ndmin=2)
    us = np.int64(1000)
    return OxfordRelativePoses(ints[:, 0] * us, ints[:, 1] * us, ints[:, 2] * us, ints[:, 3] * us,
                               xyy[:, 0], -xyy[:, 1], -xyy[:, 2])


def compose_relative_poses(rel: OxfordRelativePoses,
                           origin_xyt: tuple[float, float, float] = (0.0, 0.0, 0.0),
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Chain the rows (each row's destination = the previous row's source) into absolute
    planar poses: ``(t_ns, xyt)`` with N + 1 poses, the first (``origin_xyt``) at the first
    row's destination time. SE(2): p_k = p_{k-1} (+) (x, y, yaw)_k."""
    if len(rel.x_m) > 1 and np.any(rel.destination_t_ns[1:] != rel.source_t_ns[:-1]):
        k = int(np.flatnonzero(rel.destination_t_ns[1:] != rel.source_t_ns[:-1])[0]) + 1
        raise ValueError(f"relative poses do not chain at row {k} "
                         f"(destination {rel.destination_t_ns[k]} ns)")
    x0, y0, th0 = origin_xyt
    theta = th0 + np.concatenate([[0.0], np.cumsum(rel.yaw_rad)])
    c, s = np.cos(theta[:-1]), np.sin(theta[:-1])
    x = x0 + np.concatenate([[0.0], np.cumsum(c * rel.x_m - s * rel.y_m)])
    y = y0 + np.concatenate([[0.0], np.cumsum(s * rel.x_m + c * rel.y_m)])
    t = np.concatenate([rel.destination_t_ns[:1], rel.source_t_ns])
    return t, np.column_stack([x, y, msgs.wrap_angle(theta)])


def _scan_paths(folder: Path) -> list[tuple[int, Path]]:
    return sorted((int(p.stem), p) for p in (folder / "radar").glob("*.png") if p.stem.isdigit())


def _beam_stream(scans: list[tuple[int, Path]],
                 config: msgs.RadarConfig) -> Iterator[tuple[int, int, str, msgs.RadarBeam]]:
    for turn, (_, path) in enumerate(scans):  # one PNG in memory at a time
        for t, beam in scan_to_beams(read_navtech_png(path), turn, config):
            yield t, 0, "beams", beam


def iter_oxford_folder(folder: str | Path, config: msgs.RadarConfig = NAVTECH_CTS350X,
                       ) -> Iterator[tuple[int, str, msgs.RadarBeam | msgs.Pose2D]]:
    """Yield ``(t_ns, stream, msg)`` in time order for an Oxford-style folder
    (``radar/<us>.png``, optional ``gt/radar_odometry.csv``): stream ``"beams"`` with every
    valid beam, stream ``"truth"`` with the ground-truth poses (frame ``odom``: identity
    at the scan before the first one, stamped at the middle of each scan)."""
    folder = Path(folder)
    scans = _scan_paths(folder)
    if not scans:
        raise FileNotFoundError(f"no radar/<timestamp>.png scans in {folder}")
    streams: list[Iterator] = [_beam_stream(scans, config)]
    gt_path = folder / "gt" / "radar_odometry.csv"
    if gt_path.exists():
        rel = read_oxford_ground_truth(gt_path)
        wanted = np.array([ts * 1000 for ts, _ in scans], dtype=np.int64)
        rel = rel.select(np.isin(rel.source_radar_t_ns, wanted))
        order = np.argsort(rel.source_t_ns)
        rel = rel.select(order)
        if len(rel.x_m):
            t, xyt = compose_relative_poses(rel)
            streams.append((int(ti), 1, "truth", msgs.Pose2D(x, y, th, frame="odom"))
                           for ti, (x, y, th) in zip(t.tolist(), xyt.tolist(), strict=True))
    for t, _, stream, msg in heapq.merge(*streams, key=lambda item: (item[0], item[1])):
        yield t, stream, msg
