"""Boreas (University of Toronto): ``radar/<us>.png`` (Navtech CIR304-H) and
``applanix/radar_poses.csv``.

Same PNG family as Oxford (see :mod:`.navtech_png`), with the dataset's own numbers:

* n_bins from the PNG width (6848 in 2024 frames, 3360 in 2020-2021 ones);
* range per bin by date: 0.0596 m before 2021-09-21 00:00 UTC (Unix 1632182400 s), 0.04381 m
  after (a firmware upgrade), decided on the first scan's time unless ``range_resolution_m``
  is given;
* range of bin k: ``k resolution - 0.31 m`` (:data:`BOREAS_RANGE_OFFSET_M`), the offset the
  Boreas documentation gives (DATA_REFERENCE.md: "provided by Navtech and independently
  verified in our own calibration experiment"; pyboreas ``calib.radar_offset``), unless
  ``range_offset_bins`` is given. Checked on the shared 2024 frame: the notch of zero beat
  frequency (the IF high-pass) in the mean power of the 200 down-chirp azimuths is at bin 8.5
  (parabola vertex; 8.3 over all 400, none in the up-chirp ones), i.e. range 0 at ``k resolution
  - 0.37 m``: the documented -0.31 m is 1.4 bins from it,
  the bin-centre convention of the Oxford SDK (``(k + 0.5) resolution``, +0.022 m at bin 0)
  0.38 m from it. pyboreas' own Cartesian images use bin centres and ignore the offset;
* nothing is blanked: pyboreas zeroes the first 2.5 m (the radome and mount echoes, a hump
  of power at every azimuth up to about 1 m); the chain's components ignore echoes nearer
  than their ``range_min_m`` (3 m by default), and the reader keeps the data as recorded;
* column 10 is **not** a validity flag: every row is kept. In Doppler-enabled frames it
  alternates 255 / 0, the up / down chirp of the azimuth (pyboreas: ``chirp_type = col10 ==
  255``, 1 = up-chirp), carried as ``RadarBeam.chirp`` (+1 / -1): a target's range differs
  between the two by ``beta`` x its radial speed (pyboreas ``calib.radar_doppler_beta``,
  0.049 s). A scan whose column 10 is not made of both 0 and 255 gives chirp 0 (not told):
  decided on the data, not by pyboreas' date (1733248400 s), which the shared frame of
  2024-12-03 15:25 UTC precedes although it alternates.

Ground truth, ``applanix/radar_poses.csv``: ``GPSTime,easting,northing,altitude,vel_east,
vel_north,vel_up,roll,pitch,heading,angvel_z,angvel_y,angvel_x``; ``GPSTime`` (us) equals the
PNG name. Positions are in a fixed East-North-Up frame. The angles are the radar frame's
orientation as pyboreas builds it (DATA_REFERENCE.md, ``yawPitchRollToRot``):
``C_enu_sensor = roll(r) pitch(p) yaw(h)`` with ``yaw(h) = [[cos h, sin h, 0], [-sin h, cos h, 0],
[0, 0, 1]]`` (and likewise roll, pitch); the radar frame's x axis (forward) in ENU is the first
column of C, so the vehicle's yaw counter-clockwise from east is
``atan2(C[1, 0], C[0, 0]) = atan2(sin r sin p cos h - cos r sin h, cos p cos h)``. With the
radar's z axis down (roll = pi, the rows of the dataset) this is ``heading`` itself; with
roll = 0 it would be ``-heading``: the reader uses the full formula, not an assumed sign.
The poses go to frame ``odom`` (first pose = identity, x forward, y left, yaw CCW).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import (
    RANGE_RESOLUTION_MAX_M,
    DatasetError,
    ImportReport,
    check_option,
    check_speed,
    enu_to_odom,
    numbers,
    read_csv_columns,
    refuse_steps_back,
    time_steps_back,
    unix_times_ns,
)
from .navtech_folder import NavtechPngDataset, timestamped_pngs

__all__ = ["BOREAS_RESOLUTION_SWITCH_S", "BOREAS_RANGE_OFFSET_M", "BoreasDataset", "boreas_range_resolution_m",
           "read_boreas_poses",
           "yaw_enu_of_boreas"]

BOREAS_RESOLUTION_SWITCH_S = 1632182400  # 2021-09-21 00:00 UTC
#: range of bin 0 (bin k at k x resolution + this), the Boreas documentation's calibrated offset
BOREAS_RANGE_OFFSET_M = -0.31
BOREAS_POSE_COLUMNS = ["GPSTime", "easting", "northing", "altitude", "vel_east", "vel_north", "vel_up",
                       "roll", "pitch", "heading", "angvel_z", "angvel_y", "angvel_x"]


def boreas_range_resolution_m(t_us: int) -> float:
    """Range per bin of a Boreas scan taken at ``t_us`` (Unix us)."""
    return 0.0596 if t_us < BOREAS_RESOLUTION_SWITCH_S * 1_000_000 else 0.04381


def yaw_enu_of_boreas(roll: np.ndarray, pitch: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Yaw (CCW from east) of the sensor's x axis for pyboreas' (roll, pitch, heading)."""
    c00 = np.cos(pitch) * np.cos(heading)
    c10 = np.sin(roll) * np.sin(pitch) * np.cos(heading) - np.cos(roll) * np.sin(heading)
    return np.arctan2(c10, c00)


def read_boreas_poses(path: Path, dropped: list[int] | None = None,
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(t_ns, easting, northing, yaw_enu)`` of ``radar_poses.csv`` (see the module doc). A
    row whose GPSTime goes back or repeats is an error, or dropped with its row number
    appended to ``dropped`` when that is a list."""
    cols = ["GPSTime", "easting", "northing", "roll", "pitch", "heading"]
    _, text = read_csv_columns(path, cols)
    t_ns = unix_times_ns(path, text[:, 0], 1000, "GPSTime")
    v = numbers(path, text[:, 1:], float)
    # UTM: |easting|, |northing| < 10^7 m; angles in radians within a turn
    bad = np.argwhere(~(np.abs(v) <= np.array([1e7, 1e7, 2 * np.pi, 2 * np.pi, 2 * np.pi])))
    if bad.size:
        i, k = (int(j) for j in bad[0])
        raise DatasetError(f"{path}: row {i + 2}: {cols[k + 1]} {text[i, k + 1]}: out of range "
                           f"({'|m| <= 1e7 m (UTM)' if k < 2 else '|rad| <= 2 pi'})")
    refuse_steps_back(t_ns, lambda i: f"{path}: row {i + 2}: GPSTime")
    back = time_steps_back(t_ns)
    if back.any() and dropped is None:
        raise DatasetError(f"{path}: row {int(np.argmax(back)) + 2}: GPSTime does not increase")
    if back.any():
        dropped += (np.flatnonzero(back) + 2).tolist()
    rows = np.flatnonzero(~back) + 2
    t_ns, v = t_ns[~back], v[~back]
    check_speed(t_ns, v[:, 0], v[:, 1], lambda i: f"{path}: row {rows[i]}: easting {float(v[i, 0])!r}, "
                f"northing {float(v[i, 1])!r}")
    return t_ns, v[:, 0], v[:, 1], yaw_enu_of_boreas(v[:, 2], v[:, 3], v[:, 4])


class BoreasDataset(NavtechPngDataset):
    """Boreas sequence folder: ``radar/<us>.png`` and optionally ``applanix/radar_poses.csv``."""

    name = "boreas"
    sensor = "navtech-cir304h"
    flag_is_valid = False

    def __init__(self, folder: str | Path, range_resolution_m: float = 0.0, azimuth_offset_deg: float = 0.0,
                 range_offset_bins: float | None = None, report: ImportReport | None = None) -> None:

        range_resolution_m = check_option("range_resolution_m", range_resolution_m, 0.0, RANGE_RESOLUTION_MAX_M,
                                          "m")
        if not range_resolution_m:
            range_resolution_m = boreas_range_resolution_m(timestamped_pngs(Path(folder))[0][0])
        if range_offset_bins is None and range_resolution_m > 0:
            range_offset_bins = BOREAS_RANGE_OFFSET_M / range_resolution_m
        super().__init__(folder, range_resolution_m, azimuth_offset_deg, range_offset_bins or 0.0, report)
        if report is not None:
            report.notes.append("column 10 is the chirp direction (255 up / 0 down, on the beams as RadarBeam.chirp), "
                                "not a validity flag: every row kept")

    def chirp_of(self, flag: np.ndarray) -> np.ndarray | None:
        """+1 (up-chirp) where column 10 is 255, -1 where 0, when the scan holds both values only."""
        if flag is None or not (np.any(flag == 255) and np.any(flag == 0) and np.all((flag == 0) | (flag == 255))):
            return None
        return np.where(flag == 255, 1, -1).astype(np.int8)

    def truth(self, report: ImportReport) -> tuple[np.ndarray, np.ndarray] | None:
        path = self.folder / "applanix" / "radar_poses.csv"
        if not path.exists():
            report.notes.append("no applanix/radar_poses.csv: no truth poses")
            return None
        dropped: list[int] = []
        t_ns, east, north, yaw = read_boreas_poses(path, dropped)
        if dropped:
            report.fact("times back", report.facts.get("times back", "") + f"; {path.name}: {len(dropped)} row(s) "
                        f"dropped (GPSTime going back or repeated; first row {dropped[0]})")
        mine = np.isin(t_ns, np.array(self.scan_stamps_us, dtype=np.int64) * 1000)
        if not mine.any():
            report.notes.append(f"{path.name}: no GPSTime equals a scan name: no truth poses")
            return None
        if mine.sum() < len(self.scan_paths):
            report.notes.append(f"{path.name}: {len(self.scan_paths) - int(mine.sum())} scan(s) without a pose")
        report.fact("truth", "Applanix post-processed GNSS/INS (the dataset's applanix/radar_poses.csv: "
                    "centimetre-level, heading known)")
        return t_ns[mine], enu_to_odom(east[mine], north[mine], yaw[mine])
