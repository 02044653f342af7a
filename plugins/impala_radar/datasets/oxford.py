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

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from impala_flow import msgs

from .common import (
    MAX_SPEED_MPS,
    RANGE_OFFSET_MAX_BINS,
    RANGE_RESOLUTION_MAX_M,
    UNIX_S_MAX,
    DatasetError,
    ImportReport,
    NavtechDataset,
    Scan,
    check_option,
    check_span,
    check_turn_period,
    gap_summary,
    navtech_config,
    numbers,
    read_csv_columns,
    read_text,
    refuse_steps_back,
    t_text,
    time_steps_back,
    unix_times_ns,
)
from .navtech_png import ccw_azimuth, read_navtech_png, reference_scan, rotation_hz_of

__all__ = ["OXFORD_RANGE_RESOLUTION_M", "OXFORD_AZIMUTH_OFFSET_DEG", "OXFORD_README_RESOLUTION_M",
           "OxfordDataset", "OxfordRelativePoses", "read_oxford_ground_truth",
           "compose_relative_poses", "timestamped_pngs"]

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
#: a row of a scan is stamped within this of the scan's file name (measured: 0 to 253 ms after it)
ROW_NAME_TOLERANCE_S = 1.0
#: a pose row's time (the scan's middle) lies within this of its scan's time (measured: 125-127 ms)
POSE_RADAR_TOLERANCE_S = 1.0


def check_rows_against_name(path: Path, t_ns: np.ndarray) -> None:
    """Every row time of scan ``path`` within :data:`ROW_NAME_TOLERANCE_S` of the time in its
    name (the other clock): rows zeroed or from another date are a :class:`DatasetError`
    naming the file, the row and both times."""
    name_ns = int(path.stem) * 1000
    d = (np.asarray(t_ns, dtype=np.int64).astype(np.float64) - float(name_ns)) / 1e9  # float: no int64 overflow
    bad = np.flatnonzero(~(np.abs(d) <= ROW_NAME_TOLERANCE_S))
    if bad.size:
        i = int(bad[0])
        raise DatasetError(f"{path}: row {i}: time {int(t_ns[i])} ns is {d[i]:+.6g} s from the file name's "
                           f"{t_text(name_ns)} s (rows within {ROW_NAME_TOLERANCE_S:g} s of it): the row times and "
                           "the scan's name disagree")


def timestamped_pngs(folder: Path, report: ImportReport | None = None) -> list[tuple[int, Path]]:
    """``radar/<timestamp>.png`` files sorted by their time; an empty or absent folder is a
    :class:`DatasetError`; other files are listed in a note of ``report``."""
    radar = folder / "radar"
    if not radar.is_dir():
        raise DatasetError(f"{folder}: no radar/ folder of Navtech PNG scans")
    pngs = sorted(radar.glob("*.png"))
    scans = sorted((int(p.stem), p) for p in pngs if p.stem.isascii() and p.stem.isdigit())
    late = [p for s, p in scans if s > UNIX_S_MAX * 1_000_000]
    if late:
        raise DatasetError(f"{late[0]}: the name is not a Unix time in us of 1970-2100")
    if not scans:
        raise DatasetError(f"{radar}: no <timestamp>.png scans")
    others = len(pngs) - len(scans)
    if others and report is not None:
        report.notes.append(f"{others} PNG file(s) in {radar} not named <timestamp>.png, not read")
    return scans


class NavtechPngDataset(NavtechDataset):
    """A folder of Navtech PNGs with row headers; the flag byte's meaning is the subclass's."""

    flag_is_valid = True
    sensor = "navtech"

    def __init__(self, folder: str | Path, range_resolution_m: float, azimuth_offset_deg: float = 0.0,
                 range_offset_bins: float = 0.5, report: ImportReport | None = None) -> None:
        self.folder = Path(folder)
        self.range_resolution_m = check_option("range_resolution_m", range_resolution_m, 0.0,
                                               RANGE_RESOLUTION_MAX_M, "m", lo_open=True)
        self.azimuth_offset_deg = check_option("azimuth_offset_deg", azimuth_offset_deg, -360.0, 360.0, "deg")
        range_offset_bins = check_option("range_offset_bins", range_offset_bins, -RANGE_OFFSET_MAX_BINS,
                                         RANGE_OFFSET_MAX_BINS, "bins")
        stamped = timestamped_pngs(self.folder, report)
        self.scan_stamps_us = [s for s, _ in stamped]
        self.scan_paths = [p for _, p in stamped]
        check_span(np.array(self.scan_stamps_us, dtype=np.int64) * 1000, f"{self.folder / 'radar'} (scan names)")
        k0, (rows, cols, _) = reference_scan(self.scan_paths)  # a bad first scan is skipped where it is read
        first = read_navtech_png(self.scan_paths[k0])
        check_rows_against_name(self.scan_paths[k0], first.timestamps_ns)
        self.shape = (rows, cols)
        try:
            rotation_hz = rotation_hz_of([s * 1000 for s in self.scan_stamps_us], first.timestamps_ns, rows)
        except DatasetError as e:
            raise DatasetError(f"{self.scan_paths[k0]}: {e}") from None
        check_turn_period(1.0 / rotation_hz, f"{self.folder / 'radar'}: {len(self.scan_paths)} scan(s) "
                          f"{self.scan_paths[0].name}-{self.scan_paths[-1].name}")
        self.config = navtech_config(
            f"{self.sensor}-{self.name}", first.power.shape[1], self.range_resolution_m,
            range_offset_m=range_offset_bins * self.range_resolution_m, beams_per_turn=rows, rotation_hz=rotation_hz)
        if report is not None:
            self._report_scan_times(report)

    def _report_scan_times(self, report: ImportReport) -> None:
        """The scans' times (file names, sorted: never back nor repeated), the index file's
        when there is one (``radar.timestamps``: lines going back or repeated, times listed
        without a PNG), and the gaps between scans, as lines of the import block."""
        stamps = np.array(self.scan_stamps_us, dtype=np.int64)
        back = "scan files: none (named by time)"
        listed_path = self.folder / "radar.timestamps"
        missing = ""
        if listed_path.is_file():
            listed = _read_timestamps(listed_path)
            drop = time_steps_back(listed)
            if drop.any():
                first = int(np.argmax(drop))
                back += (f"; {listed_path.name}: {int(drop.sum())} line(s) dropped (time going back or repeated; "
                         f"first line {first + 1})")
            listed = listed[~drop]
            absent = np.setdiff1d(listed, stamps)
            absent = absent[(absent > stamps[0]) & (absent < stamps[-1])]  # a sample may be a part of the drive
            if absent.size:
                missing = (f"; {absent.size} scan(s) listed in {listed_path.name} without a PNG (first "
                           f"{int(absent[0])}.png), not read")
            unlisted = np.setdiff1d(stamps, listed)
            if unlisted.size:
                report.notes.append(f"{unlisted.size} PNG file(s) not listed in {listed_path.name} (first "
                                    f"{int(unlisted[0])}.png): read")
        report.fact("times back", back)
        report.fact("radar gaps", gap_summary(stamps * 1000, 1e9 / self.config.rotation_hz,
                                              [f"{s}.png" for s in self.scan_stamps_us]) + missing)

    def chirp_of(self, flag: np.ndarray) -> np.ndarray | None:
        """``RadarBeam.chirp`` of each row from the flag byte (column 10), or None: not told."""
        return None

    def read_scan(self, k: int) -> Scan:
        path = self.scan_paths[k]
        s = read_navtech_png(path, shape=self.shape)
        check_rows_against_name(path, s.timestamps_ns)
        keep = s.valid if self.flag_is_valid else np.ones(s.valid.shape, dtype=bool)
        return Scan(path, s.timestamps_ns, ccw_azimuth(s.azimuth_rad, self.azimuth_offset_deg), s.power, keep,
                    "Oxford valid flag (column 10) != 255", self.chirp_of(s.flag))

    def duration_hint_ns(self) -> int | None:
        return (self.scan_stamps_us[-1] - self.scan_stamps_us[0]) * 1000 + int(1e9 / self.config.rotation_hz)


def _read_timestamps(path: Path) -> np.ndarray:
    """The first column (us) of an Oxford ``<sensor>.timestamps`` file, in file order; a step
    back of more than a clock quirk is a :class:`DatasetError` naming the line."""
    out, lines = [], []
    for n, line in enumerate(read_text(path, "'<timestamp_us> <chunk>' lines").splitlines(), start=1):
        parts = line.split()
        if not parts:
            continue
        if not (parts[0].isascii() and parts[0].isdigit()):
            raise DatasetError(f"{path}: line {n}: expected '<timestamp_us> <chunk>', got {line.strip()[:80]!r}")
        if int(parts[0]) > UNIX_S_MAX * 1_000_000:
            raise DatasetError(f"{path}: line {n}: {parts[0][:40]} is not a Unix time in us of 1970-2100")
        out.append(int(parts[0]))
        lines.append(n)
    t = np.array(out, dtype=np.int64)
    refuse_steps_back(t * 1000, lambda i: f"{path}: line {lines[i]}")
    return t


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
