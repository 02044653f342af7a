"""R-SLAM map matching: 3-D correlation (two translations, one rotation) of the current
panoramic P with the global map G (seed 1 §4.1.1, eq. 5).

For a few rotations P_k of the panoramic around the predicted heading, the 2-D correlation
C(i, j, k) with G is computed only over a search window around the predicted position,
normalised as :func:`cv2.matchTemplate`'s ``TM_CCORR_NORMED`` (:class:`_Correlator`): the
map window's DFT is taken once per level and each rotation costs one DFT of the template,
and the inverse of the spectrum product at the valid shifts only (2.8 ms for a 601-cell template
where matchTemplate, transforming the window again for every rotation, takes 16 ms; the poses
equal matchTemplate's to 2e-5 m and 5e-5 deg on 60 Beynes and RADIATE turns).
``scipy.signal.fftconvolve`` computes the full M_G + M_P - 1 plane of eq. (5) and
``cv2.phaseCorrelate`` neither restricts the search nor tolerates a half-empty map. The
normalisation by the local map energy keeps bright, often-seen places (metal sheds) from
attracting the peak.

Coarse to fine: the rotations are correlated at ``match_cell_m`` (the map downsampled by
area averaging; climbed from the expected one, not all of the span: :func:`_coarse`), then
the best rotation is refined at the map's own cells: half steps climbed from it (from the
half step the coarse peaks' parabola points to; at most two each way, three rotations when the
peak is there) and a parabola through the best three; the translation peak, on the surface at
that rotation interpolated from those three (quadratic in the rotation), is refined to a
fraction of a cell by parabolas along x and y. The standard deviations come from the peak's
3 dB (half-power) width (seed 1, after eq. 5): a Gaussian of the same curvature and height
``h`` above the background has ``sigma^2 = h / |C''|``, i.e. the covariance ``h (-H)^-1``
with ``H`` the Hessian of the correlation at the peak.

With a thread pool (R-SLAM's ``threads``), the rotations of each level are shared among the
threads, the fine panoramic is prepared and the fine templates transformed on a helper while
the calling thread prepares the map windows (:func:`match_to_map`): every piece is the same
computation on the same data whichever thread runs it, so the poses are bit-identical to one
thread's.

Both images are lightly smoothed (``smooth_m``, at least 0.6 cell) and reduced to their
local contrast over ``contrast_m`` (3 m: it removes the R^-4 trend and the level of each
kind of clutter, keeping bushes, trees and walls against the grass). They are expected on a
compressed scale (R-SLAM passes A in dB, see :mod:`impala_slam.rslam.component`); the template is not
weighted by alpha(d) by default since the map holds the weighted mean of A (eq. 6).
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from concurrent.futures import Executor, Future
from dataclasses import dataclass

import cv2
import numpy as np

from impala_flow.msgs import Grid

from ..tilemap import TileMap, warp_grid_to_map
from .sharing import Shared, resolved, scratch, shared_map

_SMOOTH_CELLS = 0.6  # Gaussian sigma applied before rotating (cells)
_CLIMB_START = 4  # coarse rotations first correlated: the steps nearest the prediction plus the hint
_CLIMB_MORE = 2  # rotations added beyond an edge at a time (one round on 2 threads)

__all__ = ["MatchParams", "MatchResult", "match_to_map", "contrast", "downsample_grid"]


@dataclass
class MatchParams:
    search_m: float = 2.0  # half-width of the translation search window
    rot_span_deg: float = 1.0  # rotations tried: prediction +- span
    rot_step_deg: float = 0.25
    match_cell_m: float = 0.4  # cell of the coarse (all-rotation) correlation
    match_range_m: float = 60.0  # radius of the panoramic used for matching
    contrast_m: float = 3.0  # local-mean window removed before correlating
    min_score: float = 0.05  # normalised correlation below this: no match
    smooth_m: float = 0.0  # Gaussian sigma (m) before correlating; at least 0.6 cell of each level
    weight_template: bool = False  # template times alpha(d) (the map's weighting)


@dataclass
class MatchResult:
    x_m: float
    y_m: float
    theta_rad: float
    cov_xyt: np.ndarray
    score: float  # normalised correlation at the peak
    valid: bool  # False: peak on the window's border, flat or too weak


def contrast(img: np.ndarray, window_cells: int, support: np.ndarray | None = None) -> np.ndarray:
    """Each observed cell minus the mean of the observed cells in the ``window_cells``-wide
    square around it (odd, at least 3): positive above the local level, negative below it
    (kept: the correlation of eq. 5 then compares patterns, not levels); 0 where not observed.
    In float32.

    The mean is taken over the observed cells only (``support``: 1 observed, 0 not; by
    default the non-zero cells), so the rim of the radar's reach and the edge of the
    mapped area do not turn into bright rings that would correlate with each other.
    """
    img = np.asarray(img, np.float32)  # float32 throughout
    k = max(3, window_cells | 1)
    if support is None:
        support = (img > 0).astype(np.float32)
    from ._jit import contrast_box  # numba: loaded at the first match, not with the plugin

    # cv2.blur of img * support and of support, then (img - mean / weight where weight > 1e-3) * support,
    # in one compiled pass (the same bits; 4 image-sized blurs and passes through memory before)
    out = np.empty(img.shape, np.float32)
    support = np.asarray(support, np.float32)
    if img.flags.writeable != support.flags.writeable:  # the compiled pass takes both read-only or neither
        img, support = np.require(img, requirements="W"), np.require(support, requirements="W")
    contrast_box(img, support, k, out)
    return out


def _finite(a: np.ndarray) -> np.ndarray:
    """``a`` as float32 with NaN and infinities read as :func:`np.nan_to_num` reads them; ``a``
    itself (not copied: callers do not write into it) when it is all finite, the usual case
    (R-SLAM's dB images)."""
    a = np.asarray(a, np.float32)
    return a if np.isfinite(a).all() else np.nan_to_num(a)


def downsample_grid(grid: Grid, cell_m: float) -> Grid:
    """``grid`` averaged onto cells of ``cell_m`` (area interpolation); NaN read as 0."""
    s = grid.cell_m / cell_m
    if abs(s - 1.0) < 1e-9:
        return grid
    data = _finite(grid.data)
    small = cv2.resize(data, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)
    shift_m = (0.5 / s - 0.5) * grid.cell_m  # centre of destination pixel 0 in source metres
    return Grid(small, grid.cell_m / s, grid.origin_x_m + shift_m, grid.origin_y_m + shift_m, grid.frame)


def _prepared(grid: Grid, cell_m: float, contrast_cells: int, smooth_cells: float = _SMOOTH_CELLS,
              radius_cells: int | None = None) -> Grid:
    """The panoramic on ``cell_m`` cells, lightly smoothed (so that rotating it by bilinear
    interpolation blurs every angle alike) and reduced to its local contrast, once per level.

    With ``radius_cells`` only the square around the radar that the matching disk of that
    radius reads is prepared (plus the smoothing and contrast windows, so the disk's cells
    are the same as over the whole image): a 100 m Navtech panoramic matched over 35 m is
    a third of the work."""
    if radius_cells is not None:  # cut in the source cells (a whole number of destination cells from the radar)
        f = max(1, int(round(cell_m / grid.cell_m)))
        half = f * (radius_cells + contrast_cells + int(math.ceil(4.0 * smooth_cells)) + 3)
        ci, cj = int(round(-grid.origin_y_m / grid.cell_m)), int(round(-grid.origin_x_m / grid.cell_m))
        i0, j0 = ci - half, cj - half
        i0, j0 = i0 + f * max(0, -i0 // f + (-i0 % f > 0)), j0 + f * max(0, -j0 // f + (-j0 % f > 0))
        grid = Grid(np.asarray(grid.data)[i0: ci + half + 1, j0: cj + half + 1], grid.cell_m,
                    grid.origin_x_m + j0 * grid.cell_m, grid.origin_y_m + i0 * grid.cell_m, grid.frame)
    g = downsample_grid(grid, cell_m)
    data = _finite(g.data)
    ox, oy = g.origin_x_m, g.origin_y_m
    support = (data > 0).astype(np.float32)
    data = contrast(cv2.GaussianBlur(data, (0, 0), smooth_cells), contrast_cells, support)
    return Grid(data, g.cell_m, ox, oy, g.frame)


class _MapCrop:
    """M and its support (:meth:`TileMap.crop_with_support`) over one region of the map, read
    once per turn: the coarse and the fine windows are read-only views of parts of it (a window
    outside it is read from the map; OpenCV sees a view as a whole image, so its borders are the
    same as a copy's)."""

    def __init__(self, tilemap: TileMap) -> None:
        self.tilemap = tilemap
        self.x0 = self.y0 = self.nx = self.ny = 0
        self.m = self.sup = np.zeros((0, 0), np.float32)

    def read(self, ix0: int, iy0: int, nx: int, ny: int) -> None:
        self.x0, self.y0, self.nx, self.ny = ix0, iy0, nx, ny
        if self.tilemap.total_normaliser:
            self.m, self.sup = self.tilemap.crop_with_support(ix0, iy0, nx, ny)
        else:  # the weighted mean in one compiled pass per tile (same bits as crop_with_support)
            from ._jit import mean_tile

            self.m, self.sup = self.tilemap.crop_with(ix0, iy0, nx, ny, mean_tile)

    def __call__(self, ix0: int, iy0: int, nx: int, ny: int) -> tuple[np.ndarray, np.ndarray]:
        i, j = iy0 - self.y0, ix0 - self.x0
        if i < 0 or j < 0 or i + ny > self.ny or j + nx > self.nx:
            self.read(ix0, iy0, nx, ny)
            return self.m, self.sup
        return self.m[i:i + ny, j:j + nx], self.sup[i:i + ny, j:j + nx]  # views: the callers only read them


def _coarse_window(cell: float, f: int, x_p: float, y_p: float, p: MatchParams,
                   search_m: float) -> tuple[float, float, int, int, int, int, int]:
    """The coarse level's geometry around the prediction: (a, cc, h_c, s_c, ix0, iy0, n_c), coarse
    cell J centred at a + J cc, the window's first coarse cell (ix0, iy0) and its side n_c."""
    cc = f * cell
    a = 0.5 * (f - 1) * cell  # coarse cell J is centred at a + J cc
    h_c = int(math.ceil(p.match_range_m / cc))
    s_c = max(1, int(math.ceil(search_m / cc)))
    ix0 = int(round((x_p - a) / cc)) - h_c - s_c
    iy0 = int(round((y_p - a) / cc)) - h_c - s_c
    return a, cc, h_c, s_c, ix0, iy0, 2 * (h_c + s_c) + 1


def _map_window(crops: _MapCrop, ix0: int, iy0: int, n: int, f: int, contrast_cells: int,
                smooth_cells: float = _SMOOTH_CELLS) -> np.ndarray:
    """Map cells (f ix0 ..., f iy0 ...) averaged by f x f into n x n, smoothed, contrast."""
    m, sup = crops(f * ix0, f * iy0, f * n, f * n)
    if f > 1:
        m = cv2.resize(m, (n, n), interpolation=cv2.INTER_AREA)
        sup = (cv2.resize(sup, (n, n), interpolation=cv2.INTER_AREA) > 0.999).astype(np.float32)
    return contrast(cv2.GaussianBlur(m, (0, 0), smooth_cells), contrast_cells, sup)


def _template(prepared: Grid, theta_rad: float, disk: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """P_k: the prepared panoramic rotated by ``theta`` onto map-aligned cells centred on
    the radar, cut to the matching disk and weighted like the map (into ``out`` if given)."""
    half = disk.shape[0] // 2
    t = warp_grid_to_map(prepared, (0.0, 0.0, theta_rad), -half, -half, 2 * half + 1, 2 * half + 1,
                         prepared.cell_m, 0.0, out=out)
    return np.multiply(t, disk, out=t)


@functools.lru_cache(maxsize=8)
def _plain_disk(half: int) -> np.ndarray:
    """1 within ``half`` cells of the centre, 0 outside; read-only, kept per size (every turn
    of a run uses the same two)."""
    r = np.arange(-half, half + 1, dtype=np.float32)
    disk = (r[None, :] ** 2 + r[:, None] ** 2 <= half * half).astype(np.float32)
    disk.setflags(write=False)
    return disk


def _disk(half: int, cell_m: float, weight: Callable[[np.ndarray], np.ndarray] | None) -> np.ndarray:
    """Disk of radius ``half`` cells around the radar, times alpha(d) when given (the weight
    the map received: the template then carries the same distance weighting as eq. 6)."""
    if weight is None:
        return _plain_disk(half)
    r = np.arange(-half, half + 1, dtype=np.float32)
    d2 = r[None, :] ** 2 + r[:, None] ** 2
    return (d2 <= half * half).astype(np.float32) * weight(np.sqrt(d2) * cell_m)


def _parabola(cm: float, c0: float, cp: float) -> tuple[float, float]:
    """Vertex offset (in samples, within +-1) and second difference of three samples."""
    d2 = cm - 2.0 * c0 + cp
    if d2 >= 0.0:
        return 0.0, d2
    return float(np.clip(0.5 * (cm - cp) / d2, -1.0, 1.0)), d2


def _dft_size(n: int) -> int:
    """The smallest 2^a, 3 2^a or 5 2^a >= n: OpenCV's fastest real DFT sizes here (640 runs in
    1.7 ms where getOptimalDFTSize's 625 takes 2.7 ms)."""
    return min(m << max(0, math.ceil(math.log2(n / m))) for m in (1, 3, 5))


@functools.lru_cache(maxsize=8)
def _corner_matrices(size: int, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The matrices of :func:`_corner_idft` for a ``size`` x ``size`` CCS spectrum and a k x k corner."""
    n, h = size, size // 2
    i = np.arange(k)
    ang = 2.0 * np.pi * np.outer(i, np.arange(n)) / n
    rows = np.concatenate([np.cos(ang), np.sin(ang)]).astype(np.float32)  # 2k x n: along u, every column
    ph = 2.0 * np.pi * np.outer(np.arange(1, h), i) / n  # v = 1 .. h - 1 against j
    cols = np.zeros((2, n, k))
    cols[0, 1:n - 1:2], cols[0, 2:n - 1:2] = 2.0 * np.cos(ph), -2.0 * np.sin(ph)
    cols[1, 1:n - 1:2], cols[1, 2:n - 1:2] = -2.0 * np.sin(ph), -2.0 * np.cos(ph)
    cols /= n * n
    # the columns v = 0 and v = h (CCS-packed along u): their own 1-D inverse, then constant / (-1)^j in j
    packed = np.zeros((k, n))
    packed[:, 0], packed[:, n - 1] = 1.0, (-1.0) ** i
    au = 2.0 * np.pi * np.outer(i, np.arange(1, h)) / n
    packed[:, 1:n - 1:2], packed[:, 2:n - 1:2] = 2.0 * np.cos(au), -2.0 * np.sin(au)
    packed /= n * n
    return rows, cols[0], cols[1], packed, np.stack([np.ones(k), (-1.0) ** i])


def _corner_idft(spec_a: np.ndarray, spec_b: np.ndarray, k: int) -> np.ndarray:
    """The k x k corner of the scaled inverse DFT (real output) of ``spec_a conj(spec_b)``, two
    CCS-packed ``size`` x ``size`` spectra (:func:`cv2.dft`'s layout), float64: the inverse
    evaluated at those k^2 cells only, as matrix products (the k outputs along u of every column,
    float32, compiled with the product: :func:`~impala_slam.rslam._jit.rows_product`; then the k
    along v, float64, on numpy: too small for BLAS's threads). 0.5 ms where the spectrum product
    and the whole 640^2 inverse take 1.7 ms for k = 9, and nearer the exact sums (1e-3 against
    2e-2 off on correlations of 9e4 of random 601-cell images); :func:`cv2.idft`'s ``nonzeroRows``
    leaves its IPP path (3-4 times slower here)."""
    from ._jit import rows_product  # numba: loaded at the first match, not with the plugin

    n = spec_a.shape[0]
    if n % 2:  # odd sizes (tiny windows) pack otherwise: the whole inverse
        prod = cv2.mulSpectrums(spec_a, spec_b, 0, conjB=True)
        return cv2.idft(prod, flags=cv2.DFT_REAL_OUTPUT | cv2.DFT_SCALE)[:k, :k].astype(np.float64)
    rows, cos_v, sin_v, packed, sign = _corner_matrices(n, k)
    r32 = scratch("corner rows", (2 * k, n))
    rows_product(rows, spec_a, spec_b, r32)
    r = r32.astype(np.float64)
    out = r[:k] @ cos_v + r[k:] @ sin_v
    # the columns v = 0 and v = n / 2, CCS-packed along u: (re, im) pairs in rows 2u - 1, 2u
    a, b = spec_a[:, (0, n - 1)], spec_b[:, (0, n - 1)]
    prod = a * b  # rows 0 and n - 1: real
    prod[1:n - 1:2] = a[1:n - 1:2] * b[1:n - 1:2] + a[2:n - 1:2] * b[2:n - 1:2]
    prod[2:n - 1:2] = a[2:n - 1:2] * b[1:n - 1:2] - a[1:n - 1:2] * b[2:n - 1:2]
    out += (packed @ prod) @ sign
    return out


class _Correlator:
    """eq. (5) normalised (``TM_CCORR_NORMED``) of many templates against one map window.

    :func:`cv2.matchTemplate` transforms the window anew for every template and returns the
    whole (n - m + 1)^2 plane through a full inverse DFT. Here the window's DFT (CCS-packed, on
    a size >= n: no circular wrap for the valid shifts) and the window energy under every
    shift (an integral image of its squares) are computed once; each template then costs one
    forward DFT, then the inverse of the spectrum product evaluated on its k x k corner only
    (k = n - m + 1, the valid shifts: :func:`_corner_idft`): 16 ms -> 2.8 ms per rotation for a
    601-cell template (``nonzeroRows`` would skip rows but leaves OpenCV's IPP path: 3-4 times
    slower here).
    The normalisation follows OpenCV's (num / (sqrt(window energy) |T|), +-1
    between 1 and 1.125 of it, 0 beyond), so the surface equals matchTemplate's to float32
    rounding. Its work arrays are per-thread scratch (:func:`~impala_slam.rslam.sharing.scratch`): a correlator is used
    up before the next one of the same DFT size is made on its thread, and its templates may be
    correlated on several threads at once (each has its own template buffer)."""

    def __init__(self, window: np.ndarray, m: int) -> None:
        n = window.shape[0]
        self.m, self.k = m, n - m + 1
        self.size = _dft_size(n)
        self.empty = not window.any()
        if self.empty:
            return
        size = self.size
        pad = scratch("window", (size, size))
        pad[:n, :n] = window
        pad[n:], pad[:n, n:] = 0.0, 0.0
        self.spectrum = cv2.dft(pad, dst=scratch("window spectrum", (size, size)))
        sq = np.square(window, dtype=np.float64, out=scratch("square", (n, n), np.float64))
        sq = cv2.integral(sq, sum=scratch("integral", (n + 1, n + 1), np.float64))
        k = self.k
        self.energy = sq[m:m + k, m:m + k] - sq[:k, m:m + k] - sq[m:m + k, :k] + sq[:k, :k]

    def __call__(self, prepared: Grid, theta_rad: float, disk: np.ndarray) -> np.ndarray:
        """C(i, j) of the template P_k (:func:`_template`) with its top-left corner at window
        cell (i, j), float32 k x k."""
        if self.empty:
            return np.zeros((self.k, self.k), np.float32)
        return self.surface(*_template_spectrum(prepared, theta_rad, disk, self.size))

    def surface(self, spectrum: np.ndarray | None, norm: float) -> np.ndarray:
        """C(i, j) of a template given by its spectrum and norm (:func:`_template_spectrum`, on
        this correlator's DFT size; only read)."""
        k = self.k
        if self.empty or spectrum is None:
            return np.zeros((k, k), np.float32)
        # the product and its inverse at the valid shifts only (the template's spectrum is left as is)
        num = _corner_idft(self.spectrum, spectrum, k)
        den = np.sqrt(np.maximum(self.energy, 0.0)) * norm
        out = np.zeros((k, k), np.float64)
        inside = np.abs(num) < den
        np.divide(num, den, out=out, where=inside)
        near = ~inside & (np.abs(num) < 1.125 * den)
        out[near] = np.sign(num[near])
        return out.astype(np.float32)


def _template_spectrum(prepared: Grid, theta_rad: float, disk: np.ndarray, size: int,
                       slot: str = "") -> tuple[np.ndarray | None, float]:
    """(DFT on ``size`` x ``size`` cells, L2 norm) of the template P_k (:func:`_template`); no
    spectrum when the template is all zero. It does not depend on the map window: the templates
    of a level can be transformed while its window is being prepared. The spectrum is this
    thread's work array ``slot`` (:func:`~impala_slam.rslam.sharing.scratch`: a fresh 1.6 MB array per rotation cost its
    page faults, 0.5-1 ms): it holds until the next spectrum of that slot on this thread."""
    m = disk.shape[0]
    buf = scratch("template", (size, size))  # per thread: the rotations may run on two
    buf[m:], buf[:m, m:] = 0.0, 0.0
    _template(prepared, theta_rad, disk, out=buf[:m, :m])
    norm = cv2.norm(buf[:m, :m])  # L2, accumulated in double
    return (cv2.dft(buf, scratch("template spectrum " + slot, (size, size))) if norm != 0.0 else None), norm


def _lap(split: dict[str, float] | None, stage: str, seconds: float) -> None:
    if split is not None:
        split[stage] = split.get(stage, 0.0) + seconds


def _coarse(crops: _MapCrop, grid: Grid | Future, pred_xyt: tuple[float, float, float], p: MatchParams, f: int,
            rot_span_deg: float, rot_step_deg: float, search_m: float,
            weight: Callable[[np.ndarray], np.ndarray] | None,
            split: dict[str, float] | None = None, pool: Executor | None = None,
            workers: int = 0, climb: bool = False,
            hint_rad: float = 0.0) -> tuple[float, float, float, float, bool, float]:
    """The rotations of the span, the whole window, on cells of ``f`` map cells:
    (x, y, theta) of the best peak, the median of its surface, whether it is on the border, and
    the vertex of the parabola through the best three rotations' peaks (in steps from theta, within
    +-1; 0 when the best is on the span's edge).
    The rotations are shared with ``workers`` threads of ``pool`` (:func:`shared_map`).

    ``climb``: not every rotation of the span (prediction + j step, j = -n .. n) is correlated.
    The four steps nearest the prediction + ``hint_rad`` come first, then more beyond the best one
    while it is on the edge of those computed (two at a time, one round on two threads; the same
    whatever the threads, since which rotations are computed can decide the best) and not on the
    span's. The steps are the span's, so the best is the span's own whenever the peaks rise to it
    from the hint (one summit within the span, the usual case): Beynes seeds 29, 31, 41 (120
    turns, ATE to the last digit) and the RADIATE head (400 turns, poses bit for bit) gave the
    same results as all the span's, with 4 correlations a Beynes turn instead of 9 (the hint,
    the last match's heading minus its prediction, follows the gyro's bias there) and 6 on
    RADIATE (constant velocity)."""
    t0 = time.thread_time()
    x_p, y_p, th_p = pred_xyt
    a, cc, h_c, s_c, ix0, iy0, n_c = _coarse_window(crops.tilemap.cell_m, f, x_p, y_p, p, search_m)
    k_c = int(round(p.contrast_m / cc))
    sm_c = max(_SMOOTH_CELLS, p.smooth_m / cc)
    crop_c = _map_window(crops, ix0, iy0, n_c, f, k_c, sm_c)
    disk_c = _disk(h_c, cc, weight)
    corr = _Correlator(crop_c, disk_c.shape[0])  # the map's side first: the panoramic may still be in the making
    coarse = _prepared(resolved(grid), cc, k_c, sm_c, h_c + 1)
    n_rot = int(round(rot_span_deg / rot_step_deg))
    step = math.radians(rot_step_deg)
    t1 = time.thread_time()
    lo, hi, cpu = -n_rot, n_rot, 0.0
    if climb:  # the rotations around the expected one first (prediction + hint), the span's steps kept
        lo = min(max(-n_rot, math.floor(hint_rad / step) - 1), n_rot - _CLIMB_START + 1)
        lo, hi = max(-n_rot, lo), min(n_rot, lo + _CLIMB_START - 1)
    more = _CLIMB_MORE  # whatever the threads: which rotations are computed decides the result
    done: dict[int, np.ndarray] = {}
    todo = list(range(lo, hi + 1))
    while todo:
        new, c = shared_map(pool, workers, lambda q: corr(coarse, th_p + step * q, disk_c), todo)
        done.update(zip(todo, new, strict=True))
        cpu += c
        peaks_d = {q: float(s.max()) for q, s in done.items()}
        best = max(range(lo, hi + 1), key=lambda q: (peaks_d[q], -q))  # the first of equal peaks, as np.argmax
        todo = []
        if best == lo and lo > -n_rot:  # on the computed range's edge, not the span's: climb on that side
            todo = list(range(max(-n_rot, lo - more), lo))
            lo = todo[0]
        elif best == hi and hi < n_rot:
            todo = list(range(hi + 1, min(n_rot, hi + more) + 1))
            hi = todo[-1]
    thetas = th_p + step * np.arange(lo, hi + 1)
    surfaces = [done[q] for q in range(lo, hi + 1)]
    peaks = np.array([s.max() for s in surfaces])
    k = int(np.argmax(peaks))
    surf = surfaces[k]
    i, j = np.unravel_index(int(np.argmax(surf)), surf.shape)
    on_edge = i in (0, surf.shape[0] - 1) or j in (0, surf.shape[1] - 1)
    _lap(split, "prepare", t1 - t0)
    _lap(split, "coarse", time.thread_time() - t1 + cpu)
    # where the parabola through the coarse peaks around the best leans (the fine climb starts there)
    lean = _parabola(peaks[k - 1], peaks[k], peaks[k + 1])[0] if 0 < k < len(peaks) - 1 else 0.0
    return a + (ix0 + j + h_c) * cc, a + (iy0 + i + h_c) * cc, float(thetas[k]), float(np.median(surf)), on_edge, lean


def match_to_map(tilemap: TileMap, grid: Grid | Future, pred_xyt: tuple[float, float, float], p: MatchParams,
                 weight: Callable[[np.ndarray], np.ndarray] | None = None, widen: float = 1.0,
                 split: dict[str, float] | None = None, pool: Executor | None = None,
                 workers: int = 0, rot_hint_rad: float = 0.0) -> MatchResult:
    """Pose of the panoramic ``grid`` in the map by 3-D correlation around ``pred_xyt`` (eq. 5).

    ``widen`` > 1 (the prediction spans that many ordinary intervals: turns missing from
    the log) first searches ``widen`` times the rotation span, at twice the coarse cell and
    rotation step, and starts the ordinary search from its peak: after a 1.6 s gap at 4 Hz
    a constant-velocity heading is off by up to 8 deg on RADIATE's Edinburgh drive, four
    times the ordinary span, while the position is still within 2-3 m (the translation
    window is not widened: a wider one found false peaks 10 m away there).

    ``split``, when given, accumulates the thread CPU seconds of each stage: ``prepare``
    (map windows, prepared panoramics, window DFTs), ``coarse`` (the rotations of the coarse
    level, with the widened search) and ``fine`` (the rotations at the map's cells, peak), the
    CPU of ``pool``'s threads included.

    ``pool`` (with ``workers`` threads for this call): the rotations of each level are shared
    among the calling thread and those (:class:`~impala_slam.rslam.sharing.Shared`), the fine
    panoramic is prepared on one of them during the coarse level and the fine templates are
    transformed there while the fine map window is prepared. ``grid`` may be a future (its dB
    image being computed on the pool): the map windows are read first. Each piece of work is the
    same computation on the same data whichever thread runs it: the result is bit-identical to ``pool=None``.

    ``rot_hint_rad``: where the coarse rotations' climb starts, as an offset from the predicted
    heading (R-SLAM passes its last match's heading minus that match's prediction): it chooses
    which of the span's rotations are correlated first, not the rotations themselves."""
    if not p.weight_template:
        weight = None
    cell = tilemap.cell_m
    f = max(1, int(round(p.match_cell_m / cell)))
    step = math.radians(p.rot_step_deg)
    h_f = int(math.ceil(p.match_range_m / cell))
    k_f = int(round(p.contrast_m / cell))
    sm_f = max(_SMOOTH_CELLS, p.smooth_m / cell)
    fine_job = None
    if pool is not None and workers >= 1:  # the fine panoramic does not depend on the coarse peak

        def prepare_fine() -> tuple[Grid, float]:
            c0 = time.thread_time()
            return _prepared(resolved(grid), cell, k_f, sm_f, h_f + 1), time.thread_time() - c0

        fine_job = pool.submit(prepare_fine)
    crops = _MapCrop(tilemap)
    if widen > 1.0:
        x_w, y_w, th_w, _, edge_w, _ = _coarse(crops, grid, pred_xyt, p, 2 * f, widen * p.rot_span_deg,
                                            2.0 * p.rot_step_deg, p.search_m, weight, split, pool, workers)
        if not edge_w:
            pred_xyt = (x_w, y_w, th_w)
    # the map is read once over the coarse window and every fine window its peak can lead to
    t0 = time.thread_time()
    s_f = f + 2
    n_f = 2 * (h_f + s_f) + 1
    a, cc, h_c, s_c, ix0, iy0, n_c = _coarse_window(cell, f, pred_xyt[0], pred_xyt[1], p, p.search_m)
    # the fine window's first cell is round(x_c / cell) - h_f - s_f, x_c = a + (i0 + j + h_c) cc, j in 0 .. 2 s_c
    lo = [min(f * i0, int(round((a + (i0 + h_c) * cc) / cell)) - h_f - s_f) for i0 in (ix0, iy0)]
    hi = [max(f * (i0 + n_c), int(round((a + (i0 + 2 * s_c + h_c) * cc) / cell)) - h_f - s_f + n_f)
          for i0 in (ix0, iy0)]
    crops.read(lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1])
    _lap(split, "prepare", time.thread_time() - t0)
    # the worker prepares the fine panoramic first, then joins the coarse rotations
    x_c, y_c, th_c, base, on_edge, lean = _coarse(crops, grid, pred_xyt, p, f, p.rot_span_deg, p.rot_step_deg,
                                            p.search_m, weight, split, pool, workers, True, rot_hint_rad)
    t0 = time.thread_time()

    # --- fine: rotations within one coarse step at the map's own cells; parabolas -----------
    fx0 = int(round(x_c / cell)) - h_f - s_f
    fy0 = int(round(y_c / cell)) - h_f - s_f
    disk_f = _disk(h_f, cell, weight)
    delta = step / 2.0
    if fine_job is None:
        fine, cpu_prep = _prepared(resolved(grid), cell, k_f, sm_f, h_f + 1), 0.0
    else:
        fine, cpu_prep = fine_job.result()  # done: the worker took it before the coarse rotations
    # the climb below starts at the half step c0 nearest the coarse peaks' parabola (its vertex, in
    # half steps, rounded): the three rotations around it are always needed, and their templates
    # are transformed by the pool while this thread prepares the map window. Started at the coarse
    # rotation itself, the climb took a fourth rotation on 39 Beynes turns in 40 (the fine peak was
    # a half step off); from c0, on 20 in 120 (3.2 fine correlations a turn instead of 3.9, or 4
    # with the guessed fourth the pool computed before). It ends at the same summit from either
    # start (the same poses, bit for bit: Beynes seeds 29, 31, 41, RADIATE head) unless the peaks
    # have two summits within the span: Beynes seed 53's turn 57 (-2, -1, 0, +1 half steps: 0.5345,
    # 0.5319, 0.5319, 0.5279) climbed from 0 stopped at 0, from c0 = -1 it reaches -2, the higher
    # one; ATE 0.0290 -> 0.0288 m, drift 0.0504 -> 0.0496 % over 120 turns
    # (on one thread each template is correlated as soon as it is transformed: its spectrum is
    # still in the cache, 1 ms per rotation cheaper than from memory)
    size_f = _dft_size(n_f)
    threaded = pool is not None and workers >= 1
    c0 = int(np.clip(round(2.0 * lean), -1, 1))
    qs = [c0 - 1, c0, c0 + 1]
    if threaded:
        specs = Shared(pool, workers, lambda q: _template_spectrum(fine, th_c + delta * q, disk_f, size_f, str(q)),
                        qs)
    crop = _map_window(crops, fx0, fy0, n_f, 1, k_f, sm_f)
    corr = _Correlator(crop, disk_f.shape[0])
    t1 = time.thread_time()
    _lap(split, "prepare", t1 - t0 + cpu_prep)
    # climb by half steps from c0, at most 2 each way from the coarse rotation: the 5 rotations of
    # the span are not all needed when the peak (the usual case) is within the three around c0
    if threaded:
        first, cpu_spec = specs.join()
        first, cpu = shared_map(pool, workers, lambda sp: corr.surface(*sp), first)
        cpu += cpu_spec
    else:
        first, cpu = [corr(fine, th_c + delta * q, disk_f) for q in qs], 0.0
    surfaces: dict[int, np.ndarray] = dict(zip(qs, first, strict=True))

    def peak(q: int) -> float:
        if q not in surfaces:
            surfaces[q] = corr(fine, th_c + delta * q, disk_f)
        return float(surfaces[q].max())

    q = c0
    while abs(q) < 2:
        up, here, down = peak(q + 1), peak(q), peak(q - 1)
        if here >= up and here >= down:
            break
        q += 1 if up > down else -1
    kf = int(np.clip(q, -1, 1))
    dth, d2th = _parabola(peak(kf - 1), peak(kf), peak(kf + 1))
    theta = th_c + delta * kf + dth * delta
    # the surface at theta interpolated (Lagrange, in the rotation) from the three it lies among,
    # not correlated again: -1 correlation of 4-5 per turn; the poses move by 0.08 mm (Beynes,
    # 40 turns) and 0.26 mm (RADIATE, 60 turns) at most from a correlation at theta
    w = (0.5 * dth * (dth - 1.0), 1.0 - dth * dth, 0.5 * dth * (dth + 1.0))
    surf = w[0] * surfaces[kf - 1] + w[1] * surfaces[kf] + w[2] * surfaces[kf + 1]
    i, j = np.unravel_index(int(np.argmax(surf)), surf.shape)
    i, j = int(np.clip(i, 1, surf.shape[0] - 2)), int(np.clip(j, 1, surf.shape[1] - 2))
    c0 = float(surf[i, j])
    dj, cxx = _parabola(surf[i, j - 1], c0, surf[i, j + 1])
    di, cyy = _parabola(surf[i - 1, j], c0, surf[i + 1, j])
    x = (fx0 + j + dj + h_f) * cell
    y = (fy0 + i + di + h_f) * cell

    # --- covariance from the peak's 3 dB width: sigma^2 = h / |C''| -------------------------
    height = max(c0 - base, 1e-6)
    cxy = 0.25 * float(surf[i + 1, j + 1] - surf[i + 1, j - 1] - surf[i - 1, j + 1] + surf[i - 1, j - 1])
    hess = np.array([[cxx, cxy], [cxy, cyy]])
    cov = np.zeros((3, 3))
    if np.all(np.linalg.eigvalsh(-hess) > 1e-9):
        cov[:2, :2] = height * np.linalg.inv(-hess) * cell * cell
    else:
        cov[:2, :2] = np.eye(2) * (p.search_m ** 2)
    cov[2, 2] = height / (-d2th) * delta * delta if d2th < 0 else math.radians(p.rot_span_deg) ** 2
    valid = bool(not on_edge and c0 >= p.min_score and np.isfinite(c0))
    _lap(split, "fine", time.thread_time() - t1 + cpu)
    return MatchResult(float(x), float(y), float(theta), cov, c0, valid)
