"""A folder of Navtech PNGs named by their time, one per antenna turn (Oxford Radar RobotCar,
Boreas): the scans' list and times, their shape and rotation rate, and the checks every such
folder gets (row times against the file names, scan rate against the sensor's). The PNG layout
itself is :mod:`.navtech_png`; each dataset's subclass adds its truth (:mod:`.oxford`,
:mod:`.boreas`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import (
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
    read_text,
    refuse_steps_back,
    t_text,
    time_steps_back,
)
from .navtech_png import ccw_azimuth, read_navtech_png, reference_scan, rotation_hz_of

__all__ = ["NavtechPngDataset", "timestamped_pngs", "check_rows_against_name", "ROW_NAME_TOLERANCE_S"]

#: a row of a scan is stamped within this of the scan's file name (measured: 0 to 253 ms after it)
ROW_NAME_TOLERANCE_S = 1.0


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
            f"{self.sensor}-{self.name}", first.counts.shape[1], self.range_resolution_m,
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
        return Scan(path, s.timestamps_ns, ccw_azimuth(s.azimuth_rad, self.azimuth_offset_deg), None, keep,
                    "Oxford valid flag (column 10) != 255", self.chirp_of(s.flag), counts=s.counts)

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
