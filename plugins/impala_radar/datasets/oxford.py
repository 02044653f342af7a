"""Oxford Radar RobotCar: ``radar/<us>.png`` (Navtech CTS350-X) and ``gt/radar_odometry.csv``.

Sensor: 400 azimuths, 3768 bins (the count from the PNG width). Range per bin
:data:`OXFORD_RANGE_RESOLUTION_M` = 4.38 cm by default, measured on the sample's ground truth
(below); the dataset's README and its SDK's ``load_radar`` say 4.32 cm
(:data:`OXFORD_README_RESOLUTION_M`), 2.1 sigma from the measurement; ``range_resolution_m``
overrides. Bin k at its centre, ``(k + 0.5)`` bins, as the SDK's ``radar_polar_to_cartesian``
samples it. Column 10 is a validity flag: rows whose flag is not 255 are dropped and counted.

Ground truth (``gt/radar_odometry.csv``) uses x forward, y **right**, yaw **clockwise**
(z down). Each row is the pose of the *source* (later) scan in the frame of the
*destination* (earlier) scan: ``T_abs(source) = T_abs(destination) (+) T_row`` (the SDK's
``abs_pose = abs_poses[-1] * rel_pose``). :func:`read_oxford_ground_truth` returns it in the
project's frame (x forward, y left, yaw counter-clockwise): y and yaw negated. The row's
``source_timestamp`` is the middle of the source scan; the truth poses are stamped there.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import impala_msgs
from impala_flow import msgs

from .common import (
    MAX_SPEED_MPS,
    DatasetError,
    ImportReport,
    iter_mission,
    navtech_config,
    numbers,
    power_of_counts,
    read_csv_columns,
    refuse_steps_back,
    time_steps_back,
    unix_times_ns,
)
from .navtech_folder import NavtechPngDataset
from .navtech_png import NavtechScan, ccw_azimuth

__all__ = ["OXFORD_RANGE_RESOLUTION_M", "OXFORD_AZIMUTH_OFFSET_DEG", "OXFORD_README_RESOLUTION_M",
           "OxfordDataset", "OxfordRelativePoses", "read_oxford_ground_truth",
           "compose_relative_poses", "NAVTECH_CTS350X", "scan_to_beams", "iter_oxford_folder"]

OXFORD_README_RESOLUTION_M = 0.0432  # the dataset's documentation
#: Range per bin, from the data: R-SLAM's along-track error of the 10 sample pairs against the
#: ground truth, (estimated - true step) / true step, is -2.53 +- 1.14 % with 4.32 cm bins
#: (ranges, hence steps, scale with the bin size), so the bins are 4.32 / (1 - 0.0253) =
#: 4.43 +- 0.05 cm. 4.32 cm is 2.1 sigma away; 4.38 cm, the value published radar-odometry
#: pipelines use on this dataset, is within 1 sigma, and is the default.
OXFORD_RANGE_RESOLUTION_M = 0.0438
#: Constant azimuth offset, from the data: with none, the same pairs' lateral error is
#: +0.95 +- 0.17 deg of the step (9 of 10 pairs to the left, +3.3 cm mean): the scans are
#: turned left of the ground truth's axes by that much (a mounting yaw), so -0.95 deg.
OXFORD_AZIMUTH_OFFSET_DEG = -0.95
#: a pose row's time (the scan's middle) lies within this of its scan's time (measured: 125-127 ms)
POSE_RADAR_TOLERANCE_S = 1.0


class OxfordDataset(NavtechPngDataset):
    """Oxford Radar RobotCar folder: ``radar/<us>.png`` and optionally ``gt/radar_odometry.csv``."""

    name = "oxford"
    sensor = "navtech-cts350x"

    def __init__(self, folder: str | Path, range_resolution_m: float = OXFORD_RANGE_RESOLUTION_M,
                 azimuth_offset_deg: float = OXFORD_AZIMUTH_OFFSET_DEG, range_offset_bins: float = 0.5,
                 report: ImportReport | None = None) -> None:
        super().__init__(folder, range_resolution_m, azimuth_offset_deg, range_offset_bins, report)

    def truth(self, report: ImportReport) -> tuple[np.ndarray, np.ndarray] | None:
        gt_path = self.folder / "gt" / "radar_odometry.csv"
        if not gt_path.exists():
            report.notes.append(f"no {gt_path.relative_to(self.folder)}: no truth poses")
            return None
        rel = read_oxford_ground_truth(gt_path)
        name = gt_path.name
        refuse_steps_back(rel.source_t_ns, lambda i: f"{gt_path}: row {i + 2}: source_timestamp")
        back = time_steps_back(rel.source_t_ns)
        if back.any():
            rows = np.flatnonzero(back) + 2
            report.fact("times back", report.facts.get("times back", "") + f"; {name}: {int(back.sum())} row(s) "
                        f"dropped (source time going back or repeated; first row {rows[0]})")
            rel = rel.select(~back)
        # the rows whose source scan lies within the scans (a scan file missing in between keeps the chain)
        first, last = self.scan_stamps_us[0] * 1000, self.scan_stamps_us[-1] * 1000
        rel = rel.select((rel.source_radar_t_ns >= first) & (rel.source_radar_t_ns <= last))
        if not len(rel.x_m):
            report.notes.append(f"{name}: no row for these scans: no truth poses")
            return None
        brk = np.flatnonzero(rel.destination_t_ns[1:] != rel.source_t_ns[:-1])
        if brk.size:
            k = int(brk[0]) + 1
            report.notes.append(f"{name}: the rows do not chain after {k} of them (destination "
                                f"{rel.destination_t_ns[k]} ns is not the previous source): truth stops there")
            rel = rel.select(np.arange(len(rel.x_m)) < k)
        report.fact("truth", "chained radar odometry (the dataset's gt/radar_odometry.csv: centimetre-level per "
                    "scan pair, drifting over the drive); heading known")
        return compose_relative_poses(rel)


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
    """Read an Oxford ``radar_odometry.csv``; y and yaw negated into the project frame.
    Missing columns or a bad row are a :class:`DatasetError` naming the file and the row."""
    path = Path(csv_path)
    cols = ["source_timestamp", "destination_timestamp", "source_radar_timestamp",
            "destination_radar_timestamp", "x", "y", "yaw"]
    _, text = read_csv_columns(path, cols)
    ints = np.column_stack([unix_times_ns(path, text[:, k], 1000, cols[k]) for k in range(4)])
    xyy = numbers(path, text[:, 4:], float)
    # each time against its scan's (the pose is stamped in the middle of the scan)
    for k, what in ((0, "source"), (1, "destination")):
        d = (ints[:, k] - ints[:, k + 2]) / 1e9
        bad = np.flatnonzero(~(np.abs(d) <= POSE_RADAR_TOLERANCE_S))
        if bad.size:
            i = int(bad[0])
            raise DatasetError(f"{path}: row {i + 2}: {what}_timestamp {text[i, k]} is {d[i]:+.6g} s from "
                               f"{what}_radar_timestamp {text[i, k + 2]} (within {POSE_RADAR_TOLERANCE_S:g} s: "
                               "the pose is the scan's)")
    # a step no vehicle makes between two scans (at most MAX_SPEED_MPS, plus 1 m) or a yaw beyond half a turn
    dt_s = np.clip((ints[:, 0] - ints[:, 1]) / 1e9, 0.0, 10.0)
    step = np.hypot(xyy[:, 0], xyy[:, 1])
    bad = np.flatnonzero(~((step <= 1.0 + MAX_SPEED_MPS * dt_s) & (np.abs(xyy[:, 2]) <= np.pi)))
    if bad.size:
        i = int(bad[0])
        raise DatasetError(f"{path}: row {i + 2}: x {text[i, 4]} m, y {text[i, 5]} m, yaw {text[i, 6]} rad over "
                           f"{dt_s[i]:.3f} s: more than {MAX_SPEED_MPS:g} m/s (+1 m) or half a turn between two scans")
    return OxfordRelativePoses(ints[:, 0], ints[:, 1], ints[:, 2], ints[:, 3], xyy[:, 0], -xyy[:, 1], -xyy[:, 2])


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


NAVTECH_CTS350X = navtech_config("navtech-cts350x-oxford", 3768, OXFORD_RANGE_RESOLUTION_M,
                                 range_offset_m=0.5 * OXFORD_RANGE_RESOLUTION_M, beams_per_turn=400,
                                 rotation_hz=4.0)
"""Navtech CTS350-X of Oxford Radar RobotCar: 4 Hz, 400 beams, 3768 bins of 4.38 cm (measured,
see :data:`~impala_radar.datasets.oxford.OXFORD_RANGE_RESOLUTION_M`), bin k at its centre. (An
import measures the rotation rate on the data instead.)"""


def scan_to_beams(scan: NavtechScan, turn: int, config: impala_msgs.RadarConfig = NAVTECH_CTS350X,
                  azimuth_offset_deg: float = 0.0,
                  db_per_count: float = 0.5) -> list[tuple[int, impala_msgs.RadarBeam]]:
    """Valid rows of ``scan`` as ``(t_ns, RadarBeam)`` in acquisition order (linear power in
    ``up``, :func:`~impala_radar.datasets.common.counts_to_power`; ``down`` empty), azimuth
    ``wrap(-a + radians(azimuth_offset_deg))``."""
    empty = np.zeros(0, dtype=np.float32)
    azimuth = ccw_azimuth(scan.azimuth_rad, azimuth_offset_deg)
    power = power_of_counts(scan.counts, db_per_count)
    return [(int(scan.timestamps_ns[i]),
             impala_msgs.RadarBeam(float(azimuth[i]), int(turn), i, power[i], empty, config))
            for i in np.flatnonzero(scan.valid).tolist()]


def iter_oxford_folder(folder: str | Path, **options: float,
                       ) -> Iterator[tuple[int, str, impala_msgs.RadarBeam | msgs.Pose2D]]:
    """``(t_ns, "beams" | "truth", message)`` in time order for an Oxford folder
    (``radar/<us>.png``, optional ``gt/radar_odometry.csv``): every valid beam, and the truth
    poses in frame ``odom`` (identity at the scan before the first one, stamped at the middle
    of each scan). ``options``: :class:`~impala_radar.datasets.oxford.OxfordDataset` parameters."""
    yield from iter_mission(OxfordDataset(folder, **options))
