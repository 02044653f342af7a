"""Panoramic images: one antenna turn -> polar image -> motion-corrected Cartesian grid.

Every beam is placed at the vehicle pose of its own time (seed 1 §4.1.1: odometer + gyro
over the turn, the correction restarting each turn) expressed relative to the pose at the
turn's reference time t_ref (its last beam). Resampling is an inverse mapping through
``cv2.remap`` (bilinear in beam and range bin): for each cell c of the grid (vehicle frame
at t_ref), the nominal beam i0 is the one whose azimuth is nearest c's bearing; c is moved
into the vehicle frame of beam i0's time, c_i = R(-phi_i) (c - t_i), whose bearing and
range give the fractional beam and bin read. One fixed-point step suffices: neighbouring
beams' poses differ by v / (B f_rot) (1.4 cm at 5 m/s), except across the turn's seam
(first/last beam), where the image itself is discontinuous (the trochoid does not close).
What the beam azimuths and the grid fix (each cell's nominal beam, its bearing's row without
motion, the cells on the disk) is kept while the turns repeat them; the per-cell arithmetic
runs in two compiled loops over the disk's cells only (:mod:`._jit`, numba), bit for bit the
float32 formula of OpenCV's ``cartToPolar`` and ``remap`` that it replaces, with
``cv2.magnitude`` kept for the ground range (IPP's rounding). graphs/oxford.yaml's settings on
RADIATE turns: scan_to_grid 16.7 -> 10.8 ms of CPU per turn (111 before issue 26), the
component 21 -> 15 ms, measured alternately on a loaded machine (bench/frontend.py); the
first grid compiles the loops once per machine, a few seconds, then loads them from numba's
cache, 0.5 s with the import. A :class:`BandPool` shares the loops (and the component's beam
normalisation) by bands of rows among its threads, each cell computed as by one thread: the
component 13.9 -> 9.1 ms of wall per turn with 2 threads, the same 14 ms of CPU (quiet machine).

Doppler compensation: the up and down spectra of a static target sit at f_r +- f_d with
f_d = 2 V f0 / c, V = -v cos(theta) (eq. 2, 7); shifting each beam's up spectrum by -f_d
and its down spectrum by +f_d before averaging them puts static targets at their true
range (at 5 m/s ahead f_d is 2.2 bins = 0.8 m).
"""

from __future__ import annotations

import functools
import math
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from impala_msgs import SPEED_OF_LIGHT_MPS, RadarConfig

__all__ = [
    "relative_beam_poses", "integrate_poses", "relative_to", "doppler_compensated_power",
    "scan_to_grid", "grid_geometry", "AzimuthTable", "normalise_beams", "BandPool",
]


def relative_beam_poses(t_ns, speed_mps: float, yaw_rate_radps: float) -> np.ndarray:
    """(B, 3) poses (x_m, y_m, theta_rad) at ``t_ns`` relative to the pose at ``t_ns[-1]``
    for constant speed and yaw rate (exact circular arc)."""
    dt = (np.asarray(t_ns, np.int64) - np.int64(np.asarray(t_ns)[-1])) * 1e-9
    th = yaw_rate_radps * dt
    if abs(yaw_rate_radps) > 1e-9:
        x = speed_mps * np.sin(th) / yaw_rate_radps
        y = speed_mps * (1.0 - np.cos(th)) / yaw_rate_radps
    else:
        x, y = speed_mps * dt, np.zeros_like(dt)
    return np.column_stack([x, y, th])


def integrate_poses(t_ns, speed_mps, yaw_rate_radps, start_xyt=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(N, 3) dead-reckoned poses at ``t_ns`` from speeds and yaw rates sampled there
    (trapezoid in heading, midpoint heading for the position), starting at ``start_xyt``."""
    t = np.asarray(t_ns, np.int64)
    dt = np.diff(t) * 1e-9
    v = np.asarray(speed_mps, float)
    w = np.asarray(yaw_rate_radps, float)
    th = start_xyt[2] + np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * dt)])
    th_mid = 0.5 * (th[1:] + th[:-1])
    ds = 0.5 * (v[1:] + v[:-1]) * dt
    x = start_xyt[0] + np.concatenate([[0.0], np.cumsum(ds * np.cos(th_mid))])
    y = start_xyt[1] + np.concatenate([[0.0], np.cumsum(ds * np.sin(th_mid))])
    return np.column_stack([x, y, th])


def relative_to(poses_xyt: np.ndarray, ref_xyt) -> np.ndarray:
    """Poses expressed in the frame of ``ref_xyt``: inv(ref) o pose."""
    dx = poses_xyt[:, 0] - ref_xyt[0]
    dy = poses_xyt[:, 1] - ref_xyt[1]
    c, s = math.cos(ref_xyt[2]), math.sin(ref_xyt[2])
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy, poses_xyt[:, 2] - ref_xyt[2]])


def _shift_rows(p: np.ndarray, shift_bins: np.ndarray) -> np.ndarray:
    """out[b, k] = p[b, k + shift_bins[b]] (linear interpolation, 0 outside)."""
    k = np.arange(p.shape[1])[None, :] + shift_bins[:, None]
    k0 = np.floor(k).astype(np.int64)
    w = (k - k0).astype(np.float32)
    rows = np.arange(p.shape[0])[:, None]
    n = p.shape[1]
    a = np.where((k0 >= 0) & (k0 < n), p[rows, np.clip(k0, 0, n - 1)], 0.0)
    b = np.where((k0 + 1 >= 0) & (k0 + 1 < n), p[rows, np.clip(k0 + 1, 0, n - 1)], 0.0)
    return ((1.0 - w) * a + w * b).astype(np.float32)


def doppler_compensated_power(up: np.ndarray, down: np.ndarray, azimuth_rad, speed_mps: float,
                              config: RadarConfig) -> np.ndarray:
    """Mean of the up and down spectra, each shifted back by the static Doppler f_d(theta)."""
    f_d_bins = (2.0 * config.f0_hz * (-speed_mps * np.cos(np.asarray(azimuth_rad)))
                / SPEED_OF_LIGHT_MPS / config.bin_hz)
    if down.size == 0:
        return np.asarray(up, np.float32)
    if up.dtype == down.dtype == np.float32 and up.shape == down.shape and up.ndim == 2:
        from ._jit import doppler_mean  # here: numba is imported at the first turn, not with the plugin

        out = np.empty(up.shape, np.float32)
        doppler_mean(np.ascontiguousarray(up), np.ascontiguousarray(down), np.asarray(f_d_bins, float), out)
        return out  # the formula below, bit for bit, in one pass
    return 0.5 * (_shift_rows(up, f_d_bins) + _shift_rows(down, -f_d_bins))


def normalise_beams(power: np.ndarray, pool: BandPool | None = None) -> np.ndarray:
    """Each beam (row) divided by its median power, its floor (float32); a beam whose median
    is 0 (blanked, all zero) is divided by its smallest positive power, or left at 0.
    ``pool``: its threads share the beams by bands (each beam the same bits)."""
    p = np.asarray(power, np.float32)
    if pool is None or pool.threads < 2 or p.ndim != 2 or p.shape[0] < 2 * pool.threads or not p.shape[1]:
        return _normalised(p)
    out = np.empty(p.shape, np.float32)
    rows = p.shape[0]
    cuts = [rows * b // pool.threads for b in range(pool.threads + 1)]
    pool.run(_normalised, [(p[cuts[b]:cuts[b + 1]], out[cuts[b]:cuts[b + 1]]) for b in range(pool.threads)])
    return out


def _normalised(p: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """:func:`normalise_beams` of float32 beams ``p``, into ``out`` if given."""
    if p.ndim == 2 and p.shape[1]:
        from .._median_jit import medians  # here: numba is imported at the first turn, not with the plugin

        floor = medians(p)  # np.median(p, axis=1) bit for bit, RADIATE 3.2 -> 1.4 ms
    else:
        floor = np.median(p, axis=1)
    bad = ~(floor > 0)
    if bad.any():
        positive = np.where(p > 0, p, np.inf).min(axis=1)
        floor[bad] = np.where(np.isfinite(positive[bad]), positive[bad], 1.0)
    return np.divide(p, floor[:, None].astype(np.float32), out=out)


@functools.lru_cache(maxsize=4)
def grid_geometry(n_half: int, cell_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Cell centres X, Y (float32, row = y, column = x, radar at the centre), their range and
    bearing in [0, 2 pi) (read-only, cached)."""
    c = (np.arange(-n_half, n_half + 1) * cell_m).astype(np.float32)
    x, y = np.meshgrid(c, c)
    r, bearing = cv2.cartToPolar(x, y)
    for a in (x, y, r, bearing):
        a.flags.writeable = False
    return x, y, r, bearing


_TWO_PI_F32 = np.float32(2.0 * math.pi)


def _uniform_rows(bearing: np.ndarray, first_rad: np.float32, per_rad: np.float32) -> np.ndarray:
    """``np.mod(bearing - first_rad, 2 pi) * per_rad + 1`` in float32, bit for bit, without
    ``np.mod`` (its fmod costs ten elementwise passes): bearing and first_rad are in
    [0, 2 pi], so the difference is in [-2 pi, 2 pi] and fmod is the identity on it;
    numpy's remainder then adds 2 pi to a negative value, and 2 pi itself wraps to 0."""
    d = cv2.subtract(bearing, float(first_rad))
    if d.size and float(d.max()) >= _TWO_PI_F32:  # a bearing of exactly 2 pi (float32): fmod is exact there
        d[d >= _TWO_PI_F32] -= _TWO_PI_F32
    cv2.add(d, float(_TWO_PI_F32), dst=d, mask=cv2.compare(d, 0.0, cv2.CMP_LT))
    d *= per_rad
    d += np.float32(1.0)
    return d


class AzimuthTable:
    """Where each bearing falls among the beams of one turn, whatever their order.

    The beams are sorted by azimuth in [0, 2 pi) (a clockwise radar's turn, a turn that
    wraps through 0, a partial turn and a missing beam all become the same problem); polar
    row ``r`` of :meth:`rows` is sorted beam ``r - 1`` with one extra row each side (the
    last beam before 0, the first after 2 pi), so a bearing maps to a fractional row by
    linear interpolation in azimuth. Between two beams further apart than ``max_gap`` times
    the nominal spacing (a partial turn, lost beams) nothing was observed: bearings there
    read the nearer beam up to half a spacing from it, and nothing (row -1) beyond.
    Duplicated azimuths keep their first beam in time (``dropped`` counts the others).
    """

    def __init__(self, azimuth_rad, max_gap: float = 2.5) -> None:
        az = np.mod(np.asarray(azimuth_rad, float), 2.0 * math.pi)
        order = np.argsort(az, kind="stable")
        az_s = az[order]
        keep = np.concatenate([[True], np.diff(az_s) > 1e-9])
        self.order, self.azimuth_rad = order[keep], az_s[keep]
        self.dropped = int(len(az) - keep.sum())
        n = len(self.azimuth_rad)
        self.n = n
        az_s = self.azimuth_rad
        self.xp = np.concatenate([[az_s[-1] - 2.0 * math.pi], az_s, [az_s[0] + 2.0 * math.pi]])
        gaps = np.diff(self.xp)  # gap before sorted beam k is gaps[k]; gaps[n] is the wrap
        self.spacing_rad = float(np.median(gaps[1:])) if n > 1 else 2.0 * math.pi
        limit = max_gap * self.spacing_rad
        self.big_gaps = np.flatnonzero(gaps > limit) if n > 1 else np.array([0, 1])
        self.uniform = bool(n > 1 and self.big_gaps.size == 0
                            and np.all(np.abs(gaps - self.spacing_rad) <= 1e-3 * self.spacing_rad))

    def rows(self, power: np.ndarray) -> np.ndarray:
        """The polar image in sorted-azimuth order with the wrap rows (float32)."""
        p = np.asarray(power, np.float32)[self.order]
        return np.concatenate([p[-1:], p, p[:1]])

    def row_of(self, bearing_rad: np.ndarray) -> np.ndarray:
        """Fractional row of :meth:`rows` for bearings in [0, 2 pi) (float32); -1 where no
        beam observed that bearing."""
        b = np.asarray(bearing_rad, np.float32)
        if self.uniform and b.size and b.ndim in (1, 2):
            return _uniform_rows(np.ascontiguousarray(b), np.float32(self.azimuth_rad[0]),
                                 np.float32(1.0 / self.spacing_rad))
        if self.uniform:
            u = np.mod(b - np.float32(self.azimuth_rad[0]), np.float32(2.0 * math.pi))
            return u * np.float32(1.0 / self.spacing_rad) + np.float32(1.0)
        row = np.interp(b, self.xp, np.arange(self.n + 2, dtype=float)).astype(np.float32)
        if self.big_gaps.size:
            half = 0.5 * self.spacing_rad
            for k in self.big_gaps.tolist():  # the gap between xp[k] and xp[k + 1]
                lo, hi = self.xp[k], self.xp[k + 1]
                inside = (b > lo) & (b < hi)
                row[inside & (b <= lo + half)] = k
                row[inside & (b >= hi - half)] = k + 1
                row[inside & (b > lo + half) & (b < hi - half)] = -10.0
        return row

    def nearest(self, row: np.ndarray) -> np.ndarray:
        """Index (into the time-ordered beams) of the beam nearest each fractional row."""
        k = np.clip(np.rint(row).astype(np.intp) - 1, -1, self.n) % self.n
        return self.order[k]


_ATAN_P = np.array([np.float32(np.float32(c) * np.float32(180.0 / math.pi))  # OpenCV's atan2_p1..p7
                    for c in (0.9997878412794807, -0.3258083974640975, 0.1555786518463281, -0.04432655554792128)]
                   + [np.float32(math.pi / 180.0)], np.float32)


class _Plan:
    """What one beam geometry (azimuths, gap limit) and one grid (half size, cell) fix, built
    once and reused while the turns keep them (a Navtech's azimuths repeat turn after turn):
    the azimuth table, each cell's nominal beam (:meth:`AzimuthTable.nearest`), the rows of
    the bearings without motion, and per disk radius the cells on the disk (:meth:`disk`)."""

    def __init__(self, azimuth_rad: np.ndarray, max_gap: float, n_half: int, cell_m: float) -> None:
        self.table = AzimuthTable(azimuth_rad, max_gap)
        self.x, self.y, self.r, self.bearing = grid_geometry(n_half, cell_m)
        self.c = np.ascontiguousarray(self.x[0])
        self.row0 = self.table.row_of(self.bearing)
        i0 = self.table.nearest(self.row0)  # a beam index: uint16 (a Navtech's 400 beams) reads faster
        self.i0 = i0.astype(np.uint16) if len(self.table.order) < 65536 else i0
        self._disks: dict[tuple, _Disk] = {}

    def disk(self, r_max: np.float32) -> _Disk:
        if r_max not in self._disks:
            self._disks[r_max] = _Disk(self, r_max)
        return self._disks[r_max]


class _Disk:
    """The cells of a plan's grid within ``r_max`` of the centre (``r <= r_max`` in float32:
    about 79 % of the square), row by row: ``spans[j]`` the columns [start, stop) of row j on
    the disk (contiguous: the range grows with |x| on a row); the packed cells' range, row
    without motion, and range read at each radar height (:meth:`r_read0`) without motion."""

    GUARD = 64  # cells each side of a packed run given to cv2.magnitude (see :meth:`magnitude`)

    def __init__(self, plan: _Plan, r_max: np.float32) -> None:
        on = plan.r <= r_max
        count = on.sum(axis=1)
        start = np.where(count > 0, on.argmax(axis=1), 0)
        self.spans = np.column_stack([start, start + count]).astype(np.int64)
        last = on.shape[1] - 1 - on[:, ::-1].argmax(axis=1)
        if np.any((count > 0) & (last - start + 1 != count)):  # a row's disk cells form one run
            raise ValueError("the disk's cells of a grid row are not contiguous")
        self.index = np.flatnonzero(on.ravel())  # row-major: the packed order
        self.n = len(self.index)
        self.r0 = self.packed(plan.r)
        self.row0 = self.packed(plan.row0)
        self._plan = plan
        self._r_read0: dict[float, np.ndarray] = {}
        self._height: dict[float, np.ndarray] = {}
        self._scratch = threading.local()  # per thread: two builders may share a plan
        self._bands: dict[int, tuple[tuple[int, int, int], ...]] = {}

    def bands(self, n: int) -> tuple[tuple[int, int, int], ...]:
        """``n`` bands of grid rows (j0, j1, k0: rows j0 to j1 - 1, row j0's first cell at packed
        index k0) holding about as many disk cells each, covering every row (kept per ``n``)."""
        if n not in self._bands:
            self._bands[n] = self._split(n)
        return self._bands[n]

    def _split(self, n: int) -> tuple[tuple[int, int, int], ...]:
        rows = len(self.spans)
        ends = np.cumsum(self.spans[:, 1] - self.spans[:, 0])
        cuts = [0] + [int(np.searchsorted(ends, self.n * b / n, side="left")) + 1 for b in range(1, n)] + [rows]
        cuts = sorted(min(max(c, 0), rows) for c in cuts)
        starts = np.concatenate([[0], ends])
        return tuple((cuts[b], cuts[b + 1], int(starts[cuts[b]])) for b in range(n) if cuts[b + 1] > cuts[b])

    def packed(self, image: np.ndarray) -> np.ndarray:
        """The disk cells of a grid-sized image, in packed order (float32)."""
        return np.ascontiguousarray(image.ravel()[self.index], np.float32)

    def scratch(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """This thread's working arrays, reused turn after turn (fresh pages cost as much as the
        loops): a float32 run of ``n`` cells with ``GUARD`` zeros each side (the ranges, written
        in its middle), one for :meth:`magnitude`'s output, and ``n`` cells (the rows)."""
        s = self._scratch
        if not hasattr(s, "run"):
            s.run = np.zeros(self.n + 2 * self.GUARD, np.float32)
            s.out = np.empty_like(s.run)
            s.row = np.empty(self.n, np.float32)
        return s.run, s.out, s.row

    def middle(self, run: np.ndarray) -> np.ndarray:
        return run[self.GUARD:self.GUARD + self.n]

    def magnitude(self, run: np.ndarray, out: np.ndarray, height_m: float) -> np.ndarray:
        """sqrt(r^2 + h^2) of the middle of a guarded run (:meth:`scratch`) as ``cv2.magnitude``
        gives it over the whole square. OpenCV (IPP) computes the first cells of a run up to a
        64-byte boundary and its last partial block with other roundings: the guards take them,
        as the square's corners (off the disk) did, so every disk cell is computed by one loop."""
        if height_m not in self._height:
            self._height[height_m] = np.full(len(run), np.float32(height_m))
        cv2.magnitude(run, self._height[height_m], out)
        return self.middle(out)

    def r_read0(self, height_m: float) -> np.ndarray:
        """The range each disk cell reads without motion: its ground range's slant range as
        ``cv2.magnitude`` gives it over the whole square (packed)."""
        if height_m not in self._r_read0:
            r = self._plan.r
            self._r_read0[height_m] = self.packed(cv2.magnitude(r, np.full_like(r, np.float32(height_m))))
        return self._r_read0[height_m]


class BandPool:
    """``threads`` threads (the caller's included) sharing :func:`scan_to_grid`'s compiled loops
    by bands of grid rows (numba, ``nogil``): each cell is computed by the same code on the same
    data whichever thread takes its band, so the grid is bit-identical with 1 thread or more.
    ``cpu_s``: the CPU time its worker threads spent (a caller timing its own thread adds it)."""

    def __init__(self, threads: int = 2) -> None:
        if threads < 1:
            raise ValueError(f"threads must be at least 1, got {threads}")
        self.threads = threads
        self._pool = ThreadPoolExecutor(threads - 1, thread_name_prefix="panoramic") if threads > 1 else None
        self._lock = threading.Lock()
        self.cpu_s = 0.0

    def _timed(self, fn, args: tuple) -> None:
        c0 = time.thread_time()
        try:
            fn(*args)
        finally:
            with self._lock:
                self.cpu_s += time.thread_time() - c0

    def run(self, fn, batch: list[tuple]) -> None:
        """``fn(*args)`` for each ``args`` of ``batch`` (no results: each writes its own rows),
        the caller taking the first."""
        if self._pool is None or len(batch) < 2:
            for args in batch:
                fn(*args)
            return
        futures = [self._pool.submit(self._timed, fn, args) for args in batch[1:]]
        try:
            fn(*batch[0])
        finally:
            for f in futures:
                f.result()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None


_PLANS: dict[tuple, _Plan] = {}


def _plan(azimuth_rad, max_gap: float, n_half: int, cell_m: float) -> _Plan:
    az = np.ascontiguousarray(azimuth_rad, float)
    key = (az.tobytes(), float(max_gap), n_half, cell_m)
    plan = _PLANS.get(key)
    if plan is None:
        if len(_PLANS) >= 4:
            _PLANS.pop(next(iter(_PLANS)))
        plan = _PLANS[key] = _Plan(az, max_gap, n_half, cell_m)
    return plan


def scan_to_grid(power: np.ndarray, azimuth_rad, beam_poses_xyt, range_per_bin_m: float,
                 cell_m: float, range_max_m: float, height_m: float = 0.0, range_offset_m: float = 0.0,
                 range_min_m: float = 0.0, max_gap: float = 2.5,
                 pool: BandPool | None = None) -> tuple[np.ndarray, tuple[float, float]]:
    """Cartesian grid (float32, row = y, column = x, radar at the centre cell, 0 where not
    observed) of a polar image ``power`` (beams, bins) whose beams were acquired at
    ``beam_poses_xyt`` (B, 3) relative to the grid's frame; also the centre (x, y) of cell
    (0, 0). The beams may come in any order and direction of rotation, any number per turn,
    with missing beams or a partial turn (:class:`AzimuthTable`); bin k is at range
    ``range_offset_m + k range_per_bin_m``. The grid is the disk of radius ``range_max_m``;
    cells that were nearer than ``range_min_m`` to the radar when their beam was acquired
    are 0 (the vehicle's body, the transmitter's leakage).

    ``height_m``: the radar's height above a flat ground. The spectra measure slant range
    R; a cell at ground range r is read at R = sqrt(r^2 + h^2) (ground-range projection).
    With h = 0 the grid is the slant-range image (a ground echo at 5 m from a radar 1.3 m
    high would land 17 cm too far, 8 cm at 10 m).

    ``pool``: a :class:`BandPool` whose threads share the compiled loops by bands of rows (the
    grid is the same bits whatever its number of threads); ``None``: this thread alone."""
    n_half = int(math.ceil(range_max_m / cell_m))
    plan = _plan(azimuth_rad, max_gap, n_half, float(cell_m))
    table = plan.table
    disk = plan.disk(np.float32(range_max_m))
    from ._jit import pad_polar, polar_cells, read_cells  # here: numba is imported at the first grid

    f32 = np.float32
    poses = np.asarray(beam_poses_xyt, float)
    if np.any(poses != 0.0):
        # each cell moved into the frame of the beam that saw it (one fixed-point step)
        px, py = poses[:, 0].astype(np.float32), poses[:, 1].astype(np.float32)
        ct, st = np.cos(poses[:, 2]).astype(np.float32), np.sin(poses[:, 2]).astype(np.float32)
        run, out, row = disk.scratch()
        r = disk.middle(run)
        head = (plan.c, disk.spans, plan.i0, px, py, ct, st, _ATAN_P, table.uniform, f32(table.azimuth_rad[0]),
                f32(1.0 / table.spacing_rad), _TWO_PI_F32)
        if pool is None:
            polar_cells(*head, 0, len(disk.spans), 0, r, row)
        else:
            pool.run(polar_cells, [head + band + (r, row) for band in disk.bands(pool.threads)])
        if not table.uniform:
            row = table.row_of(row)
        r_read = disk.magnitude(run, out, height_m) if height_m > 0.0 else r
    else:
        r, row = disk.r0, disk.row0
        r_read = disk.r_read0(height_m) if height_m > 0.0 else r
    grid = np.empty(plan.r.shape, np.float32)  # cells off the disk or blanked at acquisition: 0
    power = np.ascontiguousarray(power, np.float32)
    pad = pad_polar(power, table.order)
    tail = (r_read, r, row, f32(range_offset_m), f32(1.0 / range_per_bin_m), f32(range_min_m), grid)
    if pool is None:
        read_cells(pad, *power.shape, disk.spans, 0, len(disk.spans), 0, *tail)
    else:
        pool.run(read_cells, [(pad, *power.shape, disk.spans) + band + tail for band in disk.bands(pool.threads)])
    origin = -n_half * cell_m
    return grid, (origin, origin)
