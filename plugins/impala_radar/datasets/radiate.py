"""RADIATE (Heriot-Watt): ``Navtech_Polar/<frame>.png``, ``Navtech_Polar.txt``, optionally
``GPS_IMU_Twist/`` and ``GPS_IMU_Twist.txt``.

* **Scans.** 8-bit grey PNG, no header bytes: rows are range bins (row 0 nearest, 576 bins
  of 0.17361 m per the dataset's documentation), columns the azimuths of one turn (400).
  n_bins and beams per turn come from the first PNG; every scan must have its shape.
* **Azimuth.** Column j is the angle ``a = 2 pi j / N`` from forward. The direction was
  checked on the data (tests/radar/test_import_radiate.py): under both hypotheses two
  consecutive scans give the same forward translation (a mirror about the forward axis keeps
  it), but only clockwise puts the car in the left lane of the road (UK traffic, nearest
  wall on the left at ~4 m, on the right at >= 9 m), as Oxford's and Boreas' Navtech encoders
  (clockwise) and the dataset's SDK say. So ``rotation="cw"`` by default and the project's
  azimuth is ``wrap(-a + radians(azimuth_offset_deg))`` (``"ccw"``: ``wrap(a + offset)``).
* **Azimuth offset** :data:`RADIATE_AZIMUTH_OFFSET_DEG` = -2.3 deg by default, measured: a car
  moves along its own forward axis, so the direction of the translation between consecutive
  scans in the radar frame (phase correlation of Cartesian renders, regressed on the turn per
  metre to remove the lever arm) is the radar's yaw against the vehicle. With no offset it is
  +2.44 +- 0.12 deg (to the left) on the shared Edinburgh drive (146 moving pairs, 2019-02-12)
  and +2.27 +- 0.06 deg on the 18 scans of fog_6_0 shipped with radiate_sdk (2019-11-27), so
  -2.3 deg (bench/readers_kits.py). The same method gives +0.97 +- 0.23 deg on the Oxford
  sample, whose ground truth gave -0.95 deg. R-SLAM's lateral steps on the 6 fog_6_0 scans go
  from +0.11 m to +0.01 m. RADIATE's own Cartesian images (radiate_sdk tiny_foggy, 18 pairs)
  draw column j at ``j 0.9 + 0.37`` deg clockwise of up (400 columns per turn, not the 399 its
  README suggests; the issue's "-0.4 deg"): the SDK's drawing convention, not the mounting.
* **Time.** ``Navtech_Polar.txt`` gives one time per frame (``Frame: 000001 Time: <Unix s>``),
  taken as the time of column 0. The rotation period P is the median interval between
  frames; column j of frame i is at ``t_i + floor(j span_i / N)`` with
  ``span_i = min(P, t_(i+1) - t_i)`` (P for the last frame), so the beam times never go back
  even when a frame time comes early.
* **Range.** Bin k at ``(k + range_offset_bins) resolution`` (0.5: bin centres, as Navtech).
* **Truth.** ``GPS_IMU_Twist/<frame>.txt`` (line 1: ``latitude, longitude, altitude``; line 5:
  the IMU orientation quaternion ``x, y, z, w``) with times in ``GPS_IMU_Twist.txt``. The
  fixes inside the scans' time span become poses in frame ``odom``: WGS-84 to a local
  East-North frame at the first fix, yaw from the quaternion taken as ENU-referenced with a
  forward-left-up body (ROS REP 103; not checked on data: the shared sample has no GPS). A
  missing folder or fixes outside the scans' times give a note, not an error.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from impala_flow import msgs

from .common import DatasetError, ImportReport, NavtechDataset, Scan, enu_to_odom, navtech_config
from .navtech_png import check_grey8, decode_grey8, png_header

__all__ = ["RADIATE_RANGE_RESOLUTION_M", "RADIATE_AZIMUTH_OFFSET_DEG", "RadiateDataset", "read_frame_times",
           "read_gps_imu", "geodetic_to_en"]

RADIATE_RANGE_RESOLUTION_M = 0.17361
#: constant added to every azimuth (CCW positive): the radar's yaw, measured (see the module doc)
RADIATE_AZIMUTH_OFFSET_DEG = -2.3
_LINE = re.compile(r"^\s*Frame:\s*(\d+)\s+Time:\s*(\d+)(?:\.(\d+))?\s*$")


def read_frame_times(path: Path, backwards: list[tuple[int, int]] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(frames, t_ns)`` of a RADIATE ``<sensor>.txt`` index; times parsed exactly to ns.
    RADIATE writes the nanosecond fraction without its leading zeros (``1549986548.10563645``
    is ``1549986548.010563645``): the fraction is padded on the left, as RADIATE's SDK does.
    A bad line or a repeated frame is a :class:`DatasetError`; a time that goes back is one
    too unless ``backwards`` is a list, which then gets ``(line, step_ns)`` of every line
    dropped for it (a receiver clock step)."""
    if not path.is_file():
        raise DatasetError(f"{path}: missing (frame times of the scans)")
    frames, times = [], []
    with open(path) as f:
        for n, line in enumerate(f, start=1):
            if not line.strip():
                continue
            m = _LINE.match(line)
            if m is None:
                raise DatasetError(f"{path}: line {n}: expected 'Frame: <n> Time: <seconds>', got {line.strip()!r}")
            frac = (m.group(3) or "0")
            if len(frac) > 9:
                raise DatasetError(f"{path}: line {n}: more than 9 digits after the point: {line.strip()!r}")
            t = int(m.group(2)) * 1_000_000_000 + int(frac)  # the digits are nanoseconds: left-padded
            if times and t < times[-1] and backwards is not None:
                backwards.append((n, t - times[-1]))
                continue
            if times and t < times[-1]:
                raise DatasetError(f"{path}: line {n}: time goes backwards ({t} ns after {times[-1]} ns)")
            if frames and int(m.group(1)) <= frames[-1]:
                raise DatasetError(f"{path}: line {n}: frame {int(m.group(1))} after frame {frames[-1]}")
            frames.append(int(m.group(1)))
            times.append(t)
    if not frames:
        raise DatasetError(f"{path}: no 'Frame: <n> Time: <seconds>' line")
    return np.array(frames, dtype=np.int64), np.array(times, dtype=np.int64)


def geodetic_to_en(lat_deg: np.ndarray, lon_deg: np.ndarray, alt_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """WGS-84 latitude, longitude, altitude to East, North (m) of the local tangent plane at
    the first point (exact ECEF rotation, no flat-earth approximation)."""
    a, f = 6378137.0, 1.0 / 298.257223563
    e2 = f * (2.0 - f)
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    n = a / np.sqrt(1.0 - e2 * np.sin(lat) ** 2)
    xyz = np.column_stack([(n + alt_m) * np.cos(lat) * np.cos(lon), (n + alt_m) * np.cos(lat) * np.sin(lon),
                           (n * (1.0 - e2) + alt_m) * np.sin(lat)])
    d = xyz - xyz[0]
    la, lo = lat[0], lon[0]
    east = -math.sin(lo) * d[:, 0] + math.cos(lo) * d[:, 1]
    north = (-math.sin(la) * math.cos(lo) * d[:, 0] - math.sin(la) * math.sin(lo) * d[:, 1]
             + math.cos(la) * d[:, 2])
    return east, north


def _fields(path: Path, lines: list[str], n: int, count: int) -> list[float]:
    if len(lines) <= n:
        raise DatasetError(f"{path}: line {n + 1}: missing ({len(lines)} lines)")
    parts = [p for p in re.split(r"[,\s]+", lines[n].strip()) if p]
    try:
        vals = [float(p) for p in parts[:count]]
    except ValueError:
        raise DatasetError(f"{path}: line {n + 1}: not numbers: {lines[n].strip()!r}") from None
    if len(vals) < count or not all(math.isfinite(v) for v in vals):
        raise DatasetError(f"{path}: line {n + 1}: expected {count} finite numbers, got {lines[n].strip()!r}")
    return vals


def read_gps_imu(folder: Path, frames: np.ndarray) -> np.ndarray:
    """``(lat, lon, alt, qx, qy, qz, qw)`` rows of ``GPS_IMU_Twist/<frame>.txt`` for ``frames``."""
    rows = []
    for fr in frames.tolist():
        path = folder / "GPS_IMU_Twist" / f"{fr:06d}.txt"
        if not path.is_file():
            raise DatasetError(f"{path}: missing (listed in GPS_IMU_Twist.txt)")
        lines = [ln for ln in path.read_text().splitlines() if ln.strip()]
        rows.append(_fields(path, lines, 0, 3) + _fields(path, lines, 4, 4))
    return np.array(rows, dtype=np.float64).reshape(-1, 7)


class RadiateDataset(NavtechDataset):
    """A RADIATE sequence folder (see the module doc)."""

    name = "radiate"

    def __init__(self, folder: str | Path, range_resolution_m: float = RADIATE_RANGE_RESOLUTION_M,
                 azimuth_offset_deg: float = RADIATE_AZIMUTH_OFFSET_DEG, range_offset_bins: float = 0.5,
                 rotation: str = "cw",
                 report: ImportReport | None = None) -> None:
        self.folder = Path(folder)
        polar = self.folder / "Navtech_Polar"
        if not polar.is_dir():
            raise DatasetError(f"{self.folder}: no Navtech_Polar/ folder of RADIATE polar scans")
        if rotation not in ("cw", "ccw"):
            raise DatasetError(f"rotation {rotation!r}: 'cw' or 'ccw'")
        if not range_resolution_m > 0:
            raise DatasetError(f"{self.folder}: range resolution {range_resolution_m} m per bin: must be > 0")
        self.frames, self.frame_t_ns = read_frame_times(self.folder / "Navtech_Polar.txt")
        self.scan_paths = [polar / f"{fr:06d}.png" for fr in self.frames.tolist()]
        listed = {p.name for p in self.scan_paths}
        unlisted = [p for p in polar.glob("*.png") if p.name not in listed]
        if unlisted and report is not None:
            report.notes.append(f"{len(unlisted)} PNG file(s) in Navtech_Polar/ without a time in "
                                f"Navtech_Polar.txt, not read")
        if not self.scan_paths[0].is_file():
            raise DatasetError(f"{self.scan_paths[0]}: missing (listed in Navtech_Polar.txt)")
        rows, cols, mode = png_header(self.scan_paths[0])
        check_grey8(self.scan_paths[0], mode)
        self.shape = (rows, cols)
        dt = np.diff(self.frame_t_ns)
        dt = dt[dt > 0]
        self.period_ns = int(np.median(dt)) if dt.size else 250_000_000
        if not dt.size and report is not None:
            report.notes.append("one frame time: rotation period taken as 0.25 s (4 Hz)")
        self.rotation, self.azimuth_offset_deg = rotation, float(azimuth_offset_deg)
        self.config = navtech_config(
            "navtech-cts350x-radiate", rows, float(range_resolution_m),
            range_offset_m=range_offset_bins * float(range_resolution_m), beams_per_turn=cols,
            rotation_hz=round(1e9 / self.period_ns, 3))

    def read_scan(self, k: int) -> Scan:
        path = self.scan_paths[k]
        if not path.is_file():
            raise DatasetError(f"{path}: missing (listed in Navtech_Polar.txt)")
        rows, cols, mode = png_header(path)
        check_grey8(path, mode)
        if (rows, cols) != self.shape:
            raise DatasetError(f"{path}: {rows} rows x {cols} columns, expected {self.shape[0]} x {self.shape[1]} "
                               f"(range bins x azimuths) like the first scan")
        img = decode_grey8(path)
        n = cols
        span = self.period_ns
        if k + 1 < len(self.frame_t_ns):
            span = min(span, int(self.frame_t_ns[k + 1] - self.frame_t_ns[k]))
        t_ns = self.frame_t_ns[k] + (np.arange(n, dtype=np.int64) * span) // n
        a = np.arange(n, dtype=np.float64) * (2.0 * np.pi / n)
        a = -a if self.rotation == "cw" else a
        azimuth = msgs.wrap_angle(a + math.radians(self.azimuth_offset_deg))
        power = np.ascontiguousarray(img.T).astype(np.float32) / np.float32(255.0)
        return Scan(path, t_ns, azimuth, power, np.ones(n, dtype=bool))

    def duration_hint_ns(self) -> int | None:
        return int(self.frame_t_ns[-1] - self.frame_t_ns[0]) + self.period_ns

    def truth(self, report: ImportReport) -> tuple[np.ndarray, np.ndarray] | None:
        if not (self.folder / "GPS_IMU_Twist").is_dir():
            report.notes.append("no GPS_IMU_Twist/ folder: no truth poses")
            return None
        back: list[tuple[int, int]] = []
        frames, t_ns = read_frame_times(self.folder / "GPS_IMU_Twist.txt", backwards=back)
        if back:
            report.notes.append(f"GPS_IMU_Twist.txt: {len(back)} fix(es) dropped, time going back (line {back[0][0]}: "
                                f"{back[0][1] / 1e9:+.3f} s)")
        first = np.concatenate([[True], np.diff(t_ns) > 0])  # RADIATE writes every fix twice
        if not first.all():
            report.notes.append(f"GPS_IMU_Twist.txt: {int((~first).sum())} repeated fix(es) merged")
        frames, t_ns = frames[first], t_ns[first]
        t0, t1 = int(self.frame_t_ns[0]), int(self.frame_t_ns[-1]) + self.period_ns
        inside = (t_ns >= t0) & (t_ns <= t1)
        if not inside.any():
            report.notes.append(f"GPS_IMU_Twist times ({t_ns[0] / 1e9:.3f}-{t_ns[-1] / 1e9:.3f} s) do not overlap "
                                f"the scans ({t0 / 1e9:.3f}-{t1 / 1e9:.3f} s): no truth poses")
            return None
        if not inside.all():
            report.notes.append(f"GPS_IMU_Twist: {int(inside.sum())} of {inside.size} fixes within the scans' times")
        g = read_gps_imu(self.folder, frames[inside])
        east, north = geodetic_to_en(g[:, 0], g[:, 1], g[:, 2])
        qx, qy, qz, qw = g[:, 3], g[:, 4], g[:, 5], g[:, 6]
        yaw = np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
        return t_ns[inside], enu_to_odom(east, north, yaw)
