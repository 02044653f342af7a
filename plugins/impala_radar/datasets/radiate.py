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
  taken as the time of column 0; the nanoseconds are written without their leading zeros and
  padded on the left (RADIATE's SDK). A frame whose time goes back or repeats the previous is
  dropped and reported. The stamps are the logger's: when it falls behind, frames are stamped
  late and catch up (:func:`turn_clock`); those go back on the radar's turn clock (option
  ``retime``). A listed frame without its PNG is not read. Column j of frame i is at
  ``t_i + floor(j span_i / N)`` with ``span_i = min(P, t_(next listed frame) - t_i)``, P the
  turn period: a turn never spreads over a gap. Gaps (an interval over 1.5 P: round(dt / P) - 1
  turns missing) are reported, never an error.
* **Range.** Bin k at ``(k + range_offset_bins) resolution`` (0.5: bin centres, as Navtech).
  The documented 0.17361 m (100 m / 576) is kept: measured on the Edinburgh head against the
  GPS (``bench/radiate_scale.py``), the radar's displacement over 4 turns (phase correlation of
  deskewed Cartesian images) over the GPS's over the same turns is 0.9994 +- 0.015 (90 %, the
  GPS's error over the 320 m drive included; 1.0009 and 0.9979 on its halves; kiss-icp on the
  strongest returns: 0.9991), i.e. 0.1737 +- 0.0027 m per bin, with the GPS on the radar's
  clock (``gps_offset_s`` below). With the GPS as stamped, and registering raw consecutive
  turns, the radar looks 3-5 % longer: the clock offset while accelerating (1.06 on the first
  half, 1.00 above 8 m/s) and the motion within a turn (+0.9 %, removed by the deskew). A
  sawtooth's Doppler range shift (V f0 / (dF Fm), 4.8-5.5 cm per m/s) is the same in both
  turns of a pair: a step changes only with the speed (< 0.1 % of a drive).
* **Truth.** ``GPS_IMU_Twist/<frame>.txt`` (line 1: ``latitude, longitude, altitude``; lines 2-4:
  the position covariance, East-North-Up as ROS's NavSatFix; line 5: the IMU orientation
  quaternion ``x, y, z, w``) with times in ``GPS_IMU_Twist.txt``. Every fix is written twice
  (merged); the log's clock stepping back (0.36 s once in the full Edinburgh sequence) is
  re-joined: the receiver kept its 20 Hz, so the stamps from the step on move to one period after
  the last one before it (:func:`rejoin_clock_steps`; dropping the fixes until the time passes
  again would leave every later fix 0.36 s off the radar's clock); a single stray stamp going
  back is dropped; a new time with exactly the previous position is a stale fix,
  merged (on the head the receiver's fix moves >= 0.5 mm every 50 ms even at rest, so an exact
  repeat is no new solution); a listed file that is missing is counted. Each is reported.
  The fixes within the scans' times become poses in frame ``odom``: WGS-84 to a local
  East-North frame, **origin at the first fix, x axis along the first known course over
  ground** (east if the car never moves). Positions are the GPS's (a consumer receiver,
  metre-level: at rest on the head, radar images unchanged, its fixes wander ~2 m in 20 s
  while its own std says 0.2-0.5 m), ``cov_xyt[:2, :2]`` its covariance rotated into odom. The
  heading is the **course over ground** (:func:`course_over_ground`: the chord over 1 s) where
  the speed is at least 2 m/s, with ``cov_xyt[2, 2] = (0.06 m/s / v)^2 + (1 deg)^2`` (see
  :data:`COURSE_MIN_SPEED_MPS`); reversing (course opposite to the IMU yaw) turns it by 180 deg.
  Elsewhere it is unknown: ``cov_xyt[2, 2] = msgs.HEADING_UNKNOWN_VAR_RAD2`` and theta held at
  the last known heading (0 before the first), so a car at rest gives a still heading. The
  IMU quaternion (taken as ENU yaw) is not the truth: on the head it differs from the course
  by -7.7 deg on average while driving (std 2.5 deg; -5.7 deg on the full drive per issue 23);
  the import block says by how much on each import. A missing folder or fixes outside the
  scans' times give a note, not an error. **The GPS stamps are late against the radar's
  clock**: a fix stamped t is taken at ``t - gps_offset_s`` (default
  :data:`RADIATE_GPS_OFFSET_S`, 1.55 s). On the Edinburgh head the radar's speed (phase
  correlation over 4 turns, independent of any clock) matches the GPS's read 1.55 s later (90 %
  CI 1.50-1.58 s; 1.56 s on the first half of the drive, 1.51 s on the second, across the GPS
  log's gaps; residual 0.16 m/s rms against 0.86 m/s unshifted); unshifted, the truth lags the
  radar by ~15 m along the track at 10 m/s (kiss-icp's ATE over the head's 320 m of driving:
  5.6 m against the GPS as stamped, 1.2 m shifted). Another sequence may have another offset: measure it
  with ``bench/radiate_scale.py``.
"""

from __future__ import annotations

import math
import os
import re
import stat
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from impala_flow import msgs

from .common import (
    MAX_SPEED_MPS,
    MIN_INTERVAL_FRACTION,
    NAVTECH_TURN_S,
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
from .navtech_png import decode_grey8, reference_scan

__all__ = ["RADIATE_RANGE_RESOLUTION_M", "RADIATE_AZIMUTH_OFFSET_DEG", "RADIATE_GPS_OFFSET_S", "RadiateDataset",
           "FrameIndex", "read_frame_times", "read_gps_imu", "geodetic_to_en", "turn_clock", "course_over_ground",
           "COURSE_MIN_SPEED_MPS", "COURSE_BASELINE_S", "GPS_VELOCITY_STD_MPS", "COURSE_STD_FLOOR_DEG"]

#: GPS fixes are stamped this late against the radar's turn clock: a fix stamped t is the
#: position at t - RADIATE_GPS_OFFSET_S. Measured on the Edinburgh head (bench/radiate_scale.py:
#: the radar's speed over 4 turns against the GPS's, 1.55 s, 90 % CI 1.50-1.58 s, halves 1.56 and
#: 1.51 s; speed residual 0.16 m/s rms against 0.86 m/s unshifted). ``gps_offset_s`` overrides.
RADIATE_GPS_OFFSET_S = 1.55
#: The dataset's documentation (100 m / 576 bins); measured against the GPS on the Edinburgh
#: head: 0.1737 +- 0.0027 m (90 %; module doc, bench/radiate_scale.py): kept.
RADIATE_RANGE_RESOLUTION_M = 0.17361
#: constant added to every azimuth (CCW positive): the radar's yaw, measured (see the module doc)
RADIATE_AZIMUTH_OFFSET_DEG = -2.3
_LINE = re.compile(r"^\s*Frame:\s*(\d+)\s+Time:\s*(\d+)(?:\.(\d+))?\s*$")

#: Course over ground: the GPS displacement over COURSE_BASELINE_S (centred on the fix) gives
#: the heading where its speed is at least COURSE_MIN_SPEED_MPS. Chosen on the Edinburgh head:
#: at rest (radar images unchanged) the receiver's fixes wander with an apparent velocity of
#: GPS_VELOCITY_STD_MPS per axis over 0.5-2 s (up to 0.21 m/s over 1 s), so 2 m/s is ten times
#: the largest wander and the course's std is about std_v / v: 1.7 deg at 2 m/s, 0.35 deg at
#: 10 m/s, plus COURSE_STD_FLOOR_DEG (the course and the IMU yaw, which has its own errors,
#: differ by 1.1 deg std at 8-12 m/s). Below 2 m/s the course and the IMU yaw differ by 8 deg std.
COURSE_MIN_SPEED_MPS = 2.0
COURSE_BASELINE_S = 1.0
GPS_VELOCITY_STD_MPS = 0.06
COURSE_STD_FLOOR_DEG = 1.0
#: A frame stamped more than this fraction of a turn after the turn clock allows is late.
LATE_TOLERANCE_TURNS = 0.1
#: Frames looked ahead to find the turn clock (a backlog drains at ~20 ms per frame on the head).
LATE_WINDOW_FRAMES = 120


@dataclass
class FrameIndex:
    """A RADIATE ``<sensor>.txt`` index as read: kept ``frames`` and ``t_ns`` with their
    ``lines``; ``padded`` lines whose nanoseconds had fewer than 9 digits; ``dropped`` lines
    ``(line, frame, step_ns)`` whose time went back (step < 0) or repeated the previous (0)."""

    path: Path
    frames: np.ndarray
    t_ns: np.ndarray
    lines: np.ndarray
    n_lines: int = 0
    padded: int = 0
    dropped: list[tuple[int, int, int]] = field(default_factory=list)
    rejoined: list[tuple[int, int, int]] = field(default_factory=list)  # (line, frame, shift_ns) of clock steps


#: a step back of the stamps followed by at least this many samples still before the time
#: before the step is the logging clock stepping back, not a stray stamp (see rejoin_clock_steps)
CLOCK_STEP_MIN_SAMPLES = 3


def rejoin_clock_steps(t_ns: np.ndarray, min_samples: int = CLOCK_STEP_MIN_SAMPLES,
                       ) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """``(t_ns, steps)``: a steady-rate log (RADIATE's GPS: a fix every 50 ms, each written twice)
    whose clock steps back keeps sampling at its rate, so every stamp from the step on is moved
    by ``shift = t_before + period - t_after`` (one median period after the last stamp before
    the step): the fixes stay continuous in time as they are in position. A step is a stamp
    before the previous one followed by at least ``min_samples`` stamps still before that time
    (a clock that stepped back by 0.36 s at 20 Hz leaves 7 fixes there); a single stray stamp
    is not one (the caller drops it). ``steps``: ``(index, shift_ns)``."""
    t = np.array(t_ns, dtype=np.int64)
    if t.size < 2:
        return t, []
    d = np.diff(t)
    period = int(np.median(d[d > 0])) if np.any(d > 0) else 0
    steps: list[tuple[int, int]] = []
    i = 1
    while i < t.size:
        if t[i] < t[i - 1]:
            still_before = t[i:] < t[i - 1]
            run = int(np.argmin(still_before)) if not still_before.all() else int(still_before.size)
            if run >= min_samples:
                shift = int(t[i - 1] + period - t[i])
                t[i:] += shift
                steps.append((i, shift))
        i += 1
    return t, steps


def read_frame_times(path: Path, equal: str = "drop", clock_steps: str = "drop") -> FrameIndex:
    """A RADIATE ``<sensor>.txt`` index; times parsed exactly to ns. RADIATE writes the
    nanosecond fraction without its leading zeros (``1549986548.10563645`` is
    ``1549986548.010563645``): the fraction is padded on the left, as RADIATE's SDK does. A
    time going back is dropped (listed in ``dropped``), and so is a time equal to the previous
    one with ``equal="drop"`` (radar frames); ``equal="keep"`` keeps it (GPS fixes written
    twice, merged by the caller). A bad line or a frame number not increasing is a
    :class:`DatasetError`."""
    if not path.exists():
        raise DatasetError(f"{path}: missing (frame times of the scans)")
    frames, times, lines, padded = [], [], [], 0
    for n, line in enumerate(read_text(path, "'Frame: <n> Time: <seconds>' lines").splitlines(), start=1):
        if not line.strip():
            continue
        m = _LINE.match(line)
        if m is None or not m.group(0).isascii():
            raise DatasetError(f"{path}: line {n}: expected 'Frame: <n> Time: <seconds>', got {line.strip()[:80]!r}")
        frac = m.group(3) or "0"
        if len(frac) > 9:
            raise DatasetError(f"{path}: line {n}: more than 9 digits after the point: {line.strip()[:80]!r}")
        if len(m.group(1)) > 9 or int(m.group(2)) > UNIX_S_MAX:
            raise DatasetError(f"{path}: line {n}: frame {m.group(1)[:40]} at {m.group(2)[:40]} s: expected a "
                               "frame number below 10^9 and a Unix time of 1970-2100")
        padded += len(frac) < 9
        frames.append(int(m.group(1)))
        times.append(int(m.group(2)) * 1_000_000_000 + int(frac))  # the digits are nanoseconds: left-padded
        lines.append(n)
    if not frames:
        raise DatasetError(f"{path}: no 'Frame: <n> Time: <seconds>' line")
    fr, t, ln = (np.array(v, dtype=np.int64) for v in (frames, times, lines))
    refuse_steps_back(t, lambda i: f"{path}: line {ln[i]} (frame {fr[i]:06d})")
    rejoined: list[tuple[int, int, int]] = []
    if clock_steps == "rejoin":
        t, steps = rejoin_clock_steps(t)
        rejoined = [(int(ln[i]), int(fr[i]), shift) for i, shift in steps]
    bad = time_steps_back(t, equal_is_back=equal == "drop")
    last = np.maximum.accumulate(t)
    dropped = [(int(ln[i]), int(fr[i]), int(t[i] - last[i - 1])) for i in np.flatnonzero(bad)]
    fr, t, ln = fr[~bad], t[~bad], ln[~bad]
    back = np.flatnonzero(np.diff(fr) <= 0)
    if back.size:
        i = int(back[0]) + 1
        raise DatasetError(f"{path}: line {ln[i]}: frame {fr[i]} after frame {fr[i - 1]}")
    return FrameIndex(path, fr, t, ln, len(lines), padded, dropped, rejoined)


def turn_clock(t_ns: np.ndarray, window: int = LATE_WINDOW_FRAMES,
               tolerance_turns: float = LATE_TOLERANCE_TURNS) -> tuple[np.ndarray, float, np.ndarray]:
    """``(turn_t_ns, period_ns, late)``: the frames' times on the radar's turn clock.

    RADIATE stamps a frame when the logger receives it: the head's stamps follow a steady
    0.2498 s clock within about 10 ms, except where the logger fell behind: frame 131 is
    stamped 0.8 s late and the next 45 frames catch up by ~17 ms each (frames 336-347 alike,
    0.27 s). The frames are late, not turns missing: the 400 frames span 399 turns of the
    clock, and while driving at 10 m/s the radar moved 2.5 m (one turn) between frames 335
    and 336, stamped 0.516 s apart.

    A frame cannot be stamped before it is acquired, so frame k was acquired at the latest at
    ``min over the next window frames j of t_j - (clock_j - clock_k)``; a frame whose stamp
    exceeds that by more than ``tolerance_turns`` of a turn is ``late`` and takes that time;
    the others keep their stamp. Turns really missing (the later frames do not catch up) stay
    gaps; so do late frames at the very end of a log (nothing after them to catch up). The
    clock's period is local (the head's drifts by 0.1 %): the median, over +-100 frames, of
    ``(t_(k+m) - t_k) / m`` (m = 20 frames, fewer in short logs) within 1 % of the overall
    median (catch-up runs and jumps excluded: they bias even the median interval to 0.249 s).
    ``period_ns``: the overall
    median."""
    t = np.asarray(t_ns, dtype=np.int64)
    n = t.size
    if n < 2:
        return t.copy(), 250e6, np.zeros(n, dtype=bool)
    m = max(1, min(20, n // 4))
    d = (t[m:] - t[:-m]) / m
    period = float(np.median(d))
    d[np.abs(d - period) > 0.01 * period] = np.nan
    half = 100
    padded = np.concatenate([np.full(half, np.nan), d, np.full(half + m, np.nan)])
    win = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)[:n]
    local = np.nanmedian(np.column_stack([win, np.full(n, period)]), axis=1)  # never an all-NaN row
    clock = np.concatenate([[0.0], np.cumsum(local[:-1])])
    r = (t - t[0]).astype(np.float64) - clock  # relative: ns since the first frame stay exact in float64
    w = max(1, min(window, n))
    ahead = np.lib.stride_tricks.sliding_window_view(np.concatenate([r, np.full(w - 1, np.inf)]), w).min(axis=1)
    late = r - ahead > tolerance_turns * period
    out = t.copy()
    out[late] = t[0] + np.rint(clock[late] + ahead[late]).astype(np.int64)
    return out, period, late


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


def read_gps_imu(folder: Path, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, found)``: for each of ``frames``, ``GPS_IMU_Twist/<frame>.txt`` as ``(lat, lon,
    alt, 9 position covariances (line 2-4, row-major), qx, qy, qz, qw)`` (16 values; NaN where
    the file is missing: ``found`` False). A file with a bad line is a :class:`DatasetError`."""
    rows = np.full((len(frames), 16), np.nan)
    found = np.zeros(len(frames), dtype=bool)
    base = str(folder / "GPS_IMU_Twist")  # plain strings: 4000 files, pathlib would double the time
    for i, fr in enumerate(frames.tolist()):
        name = f"{base}/{fr:06d}.txt"
        try:  # non-blocking: a pipe named like a fix must not hang the import
            fd = os.open(name, os.O_RDONLY | os.O_NONBLOCK)
        except FileNotFoundError:
            continue
        except OSError:
            fd = -1
        try:
            if fd < 0 or not stat.S_ISREG(os.fstat(fd).st_mode):
                raise OSError
            text = os.read(fd, _GPS_FILE_MAX_BYTES).decode("utf-8")  # the 5 lines read are the first 300 bytes
        except (OSError, UnicodeDecodeError):  # a folder, a pipe, unreadable, binary: said with the file and line
            text = read_text(Path(name), "a GPS/IMU text file")
        finally:
            if fd >= 0:
                os.close(fd)
        head = text.split("\n", 5)[:5]
        try:  # the common case in one go; any doubt goes through _fields for a located message
            vals = [float(v) for v in " ".join(head).replace(",", " ").split()]
            ok = len(vals) == 16 and [len(ln.replace(",", " ").split()) for ln in head] == [3, 3, 3, 3, 4]
        except ValueError:
            ok = False
        if not ok or not math.isfinite(sum(vals)):
            lines = [ln for ln in text.splitlines() if ln.strip()]
            path = Path(name)
            vals = (_fields(path, lines, 0, 3) + _fields(path, lines, 1, 3) + _fields(path, lines, 2, 3)
                    + _fields(path, lines, 3, 3) + _fields(path, lines, 4, 4))
        _check_fix(Path(name), vals)
        rows[i] = vals
        found[i] = True
    return rows, found


_GPS_FILE_MAX_BYTES = 1 << 16
#: what a GPS fix may hold: WGS-84 degrees, altitude (m; the Dead Sea to the highest roads and beyond),
#: position variances (m^2, >= 0: ROS writes zeros when unknown)
_FIX_BOUNDS = ((0, "latitude", -90.0, 90.0, "deg"), (1, "longitude", -180.0, 180.0, "deg"),
               (2, "altitude", -500.0, 9000.0, "m"))


def _check_fix(path: Path, vals: list[float]) -> None:
    for k, what, lo, hi, unit in _FIX_BOUNDS:
        if not lo <= vals[k] <= hi:
            raise DatasetError(f"{path}: line 1: {what} {vals[k]!r} {unit}: expected {lo:g} to {hi:g} {unit}")
    for k in (3, 7, 11):
        if not 0.0 <= vals[k] <= 1e12:
            raise DatasetError(f"{path}: line {2 + (k - 3) // 4}: position variance {vals[k]!r} m^2: expected 0 "
                               "to 1e12")
    if not all(abs(v) <= 1e12 for v in vals[3:12]):
        raise DatasetError(f"{path}: lines 2-4: a position covariance over 1e12 m^2")


def course_over_ground(t_ns: np.ndarray, east_m: np.ndarray, north_m: np.ndarray,
                       baseline_s: float = COURSE_BASELINE_S) -> tuple[np.ndarray, np.ndarray]:
    """``(course_enu_rad, speed_mps)`` at each fix: the displacement from the last fix at or
    before ``t - baseline/2`` to the first at or after ``t + baseline/2`` (actual fixes, so a
    chord across a gap of the log; the first or last fix at the ends); speed 0 where those
    fixes span less than 0.4 or more than 3 baselines."""
    t = np.asarray(t_ns, dtype=np.int64)
    half = int(round(baseline_s * 5e8))
    a = np.maximum(np.searchsorted(t, t - half, side="right") - 1, 0)
    b = np.minimum(np.searchsorted(t, t + half, side="left"), t.size - 1)
    span_s = (t[b] - t[a]) / 1e9
    de, dn = east_m[b] - east_m[a], north_m[b] - north_m[a]
    ok = (span_s >= 0.4 * baseline_s) & (span_s <= 3.0 * baseline_s)
    speed = np.zeros(t.size)
    speed[ok] = np.hypot(de[ok], dn[ok]) / span_s[ok]
    return np.arctan2(dn, de), speed


class RadiateDataset(NavtechDataset):
    """A RADIATE sequence folder (see the module doc)."""

    name = "radiate"

    def __init__(self, folder: str | Path, range_resolution_m: float = RADIATE_RANGE_RESOLUTION_M,
                 azimuth_offset_deg: float = RADIATE_AZIMUTH_OFFSET_DEG, range_offset_bins: float = 0.5,
                 rotation: str = "cw", report: ImportReport | None = None, retime: bool = True,
                 gps_offset_s: float = RADIATE_GPS_OFFSET_S) -> None:
        self.folder = Path(folder)
        gps_offset_s = check_option("gps_offset_s", gps_offset_s, -60.0, 60.0, "s")
        range_resolution_m = check_option("range_resolution_m", range_resolution_m, 0.0, RANGE_RESOLUTION_MAX_M,
                                          "m", lo_open=True)
        azimuth_offset_deg = check_option("azimuth_offset_deg", azimuth_offset_deg, -360.0, 360.0, "deg")
        range_offset_bins = check_option("range_offset_bins", range_offset_bins, -RANGE_OFFSET_MAX_BINS,
                                         RANGE_OFFSET_MAX_BINS, "bins")
        self.gps_offset_ns = int(round(gps_offset_s * 1e9))
        polar = self.folder / "Navtech_Polar"
        if not polar.is_dir():
            raise DatasetError(f"{self.folder}: no Navtech_Polar/ folder of RADIATE polar scans")
        if rotation not in ("cw", "ccw"):
            raise DatasetError(f"rotation {rotation!r}: 'cw' or 'ccw'")
        report = report if report is not None else ImportReport()
        self.report = report
        idx = read_frame_times(self.folder / "Navtech_Polar.txt", equal="drop")
        if idx.t_ns.size > 1:  # the frames come no faster than the sensor turns (median over m frames)
            m = max(1, min(20, idx.t_ns.size // 4))
            check_turn_period(float(np.median((idx.t_ns[m:] - idx.t_ns[:-m]) / m)) / 1e9,
                              f"{idx.path}: lines {idx.lines[0]}-{idx.lines[-1]}, {idx.t_ns.size} frames in "
                              f"{(idx.t_ns[-1] - idx.t_ns[0]) / 1e9:.3f} s")
        # a frame stamped less than half a turn after the last one kept is no new turn: dropped and counted
        # (stamps are late, never early; the real logs' shortest interval is 0.214 s, a backlog catching up)
        short = _too_soon(idx.t_ns, int(MIN_INTERVAL_FRACTION * NAVTECH_TURN_S * 1e9))
        if short.any():
            i = int(np.argmax(short))
            before = int(idx.t_ns[:i][~short[:i]][-1])
            short_text = (f"{int(short.sum())} frame(s) dropped: stamped less than "
                          f"{MIN_INTERVAL_FRACTION * NAVTECH_TURN_S:g} s (half the sensor's turn) after the frame "
                          f"kept before (first line {idx.lines[i]}, frame {idx.frames[i]:06d}, "
                          f"{(int(idx.t_ns[i]) - before) / 1e9:+.3f} s)")
            idx = FrameIndex(idx.path, idx.frames[~short], idx.t_ns[~short], idx.lines[~short], idx.n_lines,
                             idx.padded, idx.dropped, idx.rejoined)
        else:
            short_text = "none (no frame less than half a turn after the one before)"
        turn_t, period, late = turn_clock(idx.t_ns) if retime else (idx.t_ns, None, None)
        if period is None:
            m = max(1, min(20, idx.t_ns.size // 4))
            period = float(np.median((idx.t_ns[m:] - idx.t_ns[:-m]) / m)) if idx.t_ns.size > 1 else 250e6
        check_span(turn_t, f"{idx.path}")
        self.index = idx
        paths = [polar / f"{fr:06d}.png" for fr in idx.frames.tolist()]
        present = np.array([p.is_file() for p in paths], dtype=bool)
        if not present.any():
            raise DatasetError(f"{paths[0]}: missing (listed in Navtech_Polar.txt), and so are all the others")
        self.frames, self.frame_t_ns, self.turn_t_ns = idx.frames[present], idx.t_ns[present], turn_t[present]
        # where each turn's beams end: the next listed frame (a frame without its PNG is still a turn)
        self.next_t_ns = np.concatenate([turn_t[1:], turn_t[-1:] + int(round(period))])[present]
        self.scan_paths = [p for p, ok in zip(paths, present, strict=True) if ok]
        listed = {p.name for p in paths}
        unlisted = [p for p in polar.glob("*.png") if p.name not in listed]
        if unlisted:
            report.notes.append(f"{len(unlisted)} PNG file(s) in Navtech_Polar/ without a time in "
                                f"Navtech_Polar.txt, not read")
        _, (rows, cols, _) = reference_scan(self.scan_paths, grey8=True)  # a bad first scan: skipped where read
        self.shape = (rows, cols)
        self.period_ns = int(round(period))
        if idx.t_ns.size < 2:
            report.notes.append("one frame time: rotation period taken as 0.25 s (4 Hz)")
        name = idx.path.name
        report.fact("padded times", f"{idx.padded} of {idx.n_lines} lines of {name} (nanoseconds written without "
                                    "their leading zeros, padded on the left as RADIATE's SDK does)")
        report.fact("repeats", "no GPS log")
        report.fact("times back", "radar: " + _dropped_text(idx, "frame"))
        if retime:
            lat = idx.t_ns - turn_t
            if late.any():
                k = int(np.argmax(lat))
                report.fact("late frames", f"{int(late.sum())} frame(s) stamped late by > "
                            f"{LATE_TOLERANCE_TURNS * period / 1e6:.0f} ms (up to {lat[k] / 1e9:.3f} s, frame "
                            f"{idx.frames[k]:06d} at t = {t_text(int(idx.t_ns[k]))} s), retimed on the turn clock "
                            f"(one turn {period / 1e9:.5f} s)")
            else:
                report.fact("late frames", f"none (stamps on the turn clock of {period / 1e9:.5f} s per turn)")
        else:
            report.fact("late frames", "not checked: frame times as stamped")
        report.fact("short turns", short_text)
        missing_png = int((~present).sum())
        gaps = gap_summary(turn_t, period, [f"frame {f:06d}" for f in idx.frames.tolist()])
        if missing_png:
            first = int(idx.frames[np.flatnonzero(~present)[0]])
            gaps += f"; {missing_png} frame(s) listed without a PNG (first {first:06d}), not read"
        report.fact("radar gaps", gaps)
        self.rotation, self.azimuth_offset_deg = rotation, float(azimuth_offset_deg)
        self.config = navtech_config(
            "navtech-cts350x-radiate", rows, float(range_resolution_m),
            range_offset_m=range_offset_bins * float(range_resolution_m), beams_per_turn=cols,
            rotation_hz=round(1e9 / self.period_ns, 3))

    def read_scan(self, k: int) -> Scan:
        path = self.scan_paths[k]
        if not path.is_file():
            raise DatasetError(f"{path}: missing (listed in Navtech_Polar.txt)")
        img = decode_grey8(path, self.shape, "range bins x azimuths")  # one read; header, shape checked first
        n = img.shape[1]
        span = min(self.period_ns, int(self.next_t_ns[k] - self.turn_t_ns[k]))  # never over a gap
        t_ns = self.turn_t_ns[k] + (np.arange(n, dtype=np.int64) * span) // n
        a = np.arange(n, dtype=np.float64) * (2.0 * np.pi / n)
        a = -a if self.rotation == "cw" else a
        azimuth = msgs.wrap_angle(a + math.radians(self.azimuth_offset_deg))
        import cv2  # here: imported by the plugin's registration already (panoramic), never by this module's users

        return Scan(path, t_ns, azimuth, None, np.ones(n, dtype=bool), counts=cv2.transpose(img))  # img.T, C order

    def duration_hint_ns(self) -> int | None:
        return int(self.turn_t_ns[-1] - self.turn_t_ns[0]) + self.period_ns

    def truth(self, report: ImportReport) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        if not (self.folder / "GPS_IMU_Twist").is_dir():
            report.notes.append("no GPS_IMU_Twist/ folder: no truth poses")
            return None
        if not (self.folder / "GPS_IMU_Twist.txt").is_file():
            report.notes.append("no GPS_IMU_Twist.txt (the fixes' times): no truth poses")
            return None
        idx = read_frame_times(self.folder / "GPS_IMU_Twist.txt", equal="keep", clock_steps="rejoin")
        name = idx.path.name
        radar_padded = report.facts.get("padded times", "").split(" (")[0]
        report.fact("padded times", f"radar {radar_padded}, GPS {idx.padded} of {idx.n_lines} lines of {name} "
                    "(nanoseconds written without their leading zeros, padded on the left as RADIATE's SDK does)")
        report.fact("times back", report.facts.get("times back", "radar: none") + "; GPS: "
                    + _dropped_text(idx, "fix"))
        if idx.rejoined:
            ln, fr, shift = idx.rejoined[0]
            report.fact("clock steps", f"GPS: {len(idx.rejoined)} step(s) back of the log's clock re-joined (line "
                        f"{ln}, fix {fr:06d}: stamps from there on moved {shift / 1e9:+.3f} s, one period after "
                        "the last stamp before the step: the receiver kept its rate)")
        rows, found = read_gps_imu(self.folder, idx.frames)
        if not found.all():
            miss = np.flatnonzero(~found)
            report.fact("GPS files", f"{miss.size} of {found.size} listed in {name} missing (first frame "
                        f"{idx.frames[miss[0]]:06d}, line {idx.lines[miss[0]]}): those fixes not read")
        t_ns, rows, fr = idx.t_ns[found], rows[found], idx.frames[found]
        if not t_ns.size:
            report.notes.append(f"{name}: no GPS file found: no truth poses")
            return None
        # RADIATE writes every fix twice: same time, same content -> merged. Same time and another
        # fix: the first kept. A new time with exactly the previous position is a stale fix (the
        # receiver's position moves by >= 0.5 mm every 50 ms even at rest on the head): merged too.
        new_t = np.concatenate([[True], np.diff(t_ns) > 0])
        first_of = np.maximum.accumulate(np.where(new_t, np.arange(t_ns.size), 0))
        same = ~new_t & np.all(rows == rows[first_of], axis=1)
        other = ~new_t & ~same
        rows, t_ns, fr = rows[new_t], t_ns[new_t], fr[new_t]
        stale = np.concatenate([[False], np.all(rows[1:, :2] == rows[:-1, :2], axis=1)])
        rows, t_ns, fr = rows[~stale], t_ns[~stale], fr[~stale]
        report.fact("repeats", f"GPS: {int(same.sum())} fix(es) written twice merged; {int(stale.sum())} stale "
                    f"(a new time with the previous position) merged; {int(other.sum())} same time with another "
                    "fix (first kept)")
        t_ns = t_ns - self.gps_offset_ns  # on the radar's clock
        report.fact("GPS clock", f"fixes taken {self.gps_offset_ns / 1e9:+.3f} s before their stamps (the GPS's "
                    "stamps are late against the radar's turn clock; measured on the Edinburgh sequence; "
                    "--gps-offset-s)")
        dt = np.diff(t_ns)
        gps_period = float(np.median(dt)) if dt.size else 50e6
        report.fact("GPS gaps", gap_summary(t_ns, gps_period, None, "fix", "fixes"))
        east, north = geodetic_to_en(rows[:, 0], rows[:, 1], rows[:, 2])
        course, speed = course_over_ground(t_ns, east, north)
        fast = np.flatnonzero(~(speed <= MAX_SPEED_MPS))
        if fast.size:
            i = int(fast[0])
            raise DatasetError(f"{self.folder / 'GPS_IMU_Twist' / f'{fr[i]:06d}.txt'}: line 1: {speed[i]:.4g} m/s over "
                               f"the {COURSE_BASELINE_S:g} s around this fix: faster than {MAX_SPEED_MPS:g} m/s")
        qx, qy, qz, qw = rows[:, 12], rows[:, 13], rows[:, 14], rows[:, 15]
        imu_yaw = np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
        t0, t1 = int(self.turn_t_ns[0]), int(self.turn_t_ns[-1]) + self.period_ns
        inside = (t_ns >= t0) & (t_ns <= t1)
        if not inside.any():
            report.notes.append(f"{name} times ({t_ns[0] / 1e9:.3f}-{t_ns[-1] / 1e9:.3f} s) do not overlap "
                                f"the scans ({t0 / 1e9:.3f}-{t1 / 1e9:.3f} s): no truth poses")
            return None
        if not inside.all():
            report.notes.append(f"{name}: {int(inside.sum())} of {inside.size} fixes within the scans' times")
        t_ns, rows, east, north = t_ns[inside], rows[inside], east[inside], north[inside]
        course, speed, imu_yaw = course[inside], speed[inside], imu_yaw[inside]
        moving = speed >= COURSE_MIN_SPEED_MPS
        # the course is the direction of travel: reversing (course opposite to the IMU's yaw,
        # which is within ~10 deg of it while driving forward) turns it by 180 deg
        reverse = moving & (np.abs(msgs.wrap_angle(course - imu_yaw)) > math.pi / 2)
        heading = np.where(reverse, course + math.pi, course)
        xyt, cov = _odom_truth(east, north, heading, moving, speed, rows[:, 3:12])
        n, k = t_ns.size, int(moving.sum())
        axis = "x along the first course over ground" if k else "x east (no course known: never moving)"
        sig = np.sqrt(np.maximum(np.stack([rows[:, 3], rows[:, 7]]), 0.0))
        report.fact("truth", f"positions from GPS (consumer receiver, metre-level; its own std {sig.min():.2f}-"
                    f"{sig.max():.2f} m) in frame odom: origin the first fix, {axis}")
        std = np.degrees(np.sqrt(cov[moving, 2, 2])) if k else np.zeros(1)
        report.fact("heading", f"from the GPS course over ground (>= {COURSE_MIN_SPEED_MPS:g} m/s over "
                    f"{COURSE_BASELINE_S:g} s; std {std.min():.1f}-{std.max():.1f} deg) on {k} of {n} poses"
                    + (f" ({int(reverse.sum())} reversing)" if reverse.any() else "")
                    + "; unknown on the rest (cov_xyt[2,2] = pi^2/3, theta held)")
        if k:
            d = np.degrees(msgs.wrap_angle(imu_yaw[moving] - heading[moving]))
            report.fact("IMU yaw", f"{d.mean():+.1f} deg from the course while moving (std {d.std():.1f} deg, "
                        f"{k} poses): not used as truth")
        return t_ns, xyt, cov


def _too_soon(t_ns: np.ndarray, min_ns: int) -> np.ndarray:
    """Mask of the times less than ``min_ns`` after the last one kept (each compared with the
    last kept: a sequential rule, hence the loop over the frames)."""
    t = np.asarray(t_ns, dtype=np.int64)
    out = np.zeros(t.size, dtype=bool)
    if t.size < 2 or np.diff(t).min() >= min_ns:
        return out
    last = int(t[0])
    for i in range(1, t.size):
        if int(t[i]) - last < min_ns:
            out[i] = True
        else:
            last = int(t[i])
    return out


def _dropped_text(idx: FrameIndex, what: str) -> str:
    if not idx.dropped:
        return "none"
    shown = "; ".join(f"line {ln} ({what} {fr:06d}, {step / 1e9:+.3f} s)" for ln, fr, step in idx.dropped[:5])
    more = f"; {len(idx.dropped) - 5} more" if len(idx.dropped) > 5 else ""
    return f"{len(idx.dropped)} line(s) dropped (time going back or repeated): {shown}{more}"


def _odom_truth(east: np.ndarray, north: np.ndarray, heading_enu: np.ndarray, known: np.ndarray,
                speed: np.ndarray, cov_enu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(xyt, cov_xyt)`` in frame odom: origin the first fix, x along the first known heading
    (east if none); theta known where ``known`` (variance from the course model), else held at
    the last known one (the first known one before it, 0 if none) with an unknown variance.
    ``cov_enu`` (N, 9): the receiver's East-North-Up covariance (ROS NavSatFix order), rotated."""
    first = int(np.argmax(known)) if known.any() else -1
    psi0 = float(heading_enu[first]) if first >= 0 else 0.0
    c, s = math.cos(psi0), math.sin(psi0)
    e, n = east - east[0], north - north[0]
    theta = np.zeros(e.size)
    if first >= 0:
        last = np.maximum.accumulate(np.where(known, np.arange(e.size), first))  # last known pose index
        theta = msgs.wrap_angle(heading_enu[last] - psi0)
    rot = np.array([[c, s], [-s, c]])  # ENU -> odom
    cov = np.zeros((e.size, 3, 3))
    cov[:, :2, :2] = rot @ cov_enu.reshape(-1, 3, 3)[:, :2, :2] @ rot.T
    var = (GPS_VELOCITY_STD_MPS / np.maximum(speed, 1e-3)) ** 2 + math.radians(COURSE_STD_FLOOR_DEG) ** 2
    cov[:, 2, 2] = np.where(known, var, msgs.HEADING_UNKNOWN_VAR_RAD2)
    return np.column_stack([c * e + s * n, -s * e + c * n, theta]), cov
