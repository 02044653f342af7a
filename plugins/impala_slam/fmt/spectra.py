"""The FMT's preparation of an image (steps 1-5 of :mod:`impala_slam.fmt.core`): resampling, threshold, dB,
taper, window and the polar magnitude spectrum; an image's spectra kept for the pairs it is in."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from impala_flow.msgs import Grid

from .correlation import coarse_rows, spectrum_columns
from .parallel import TaskPool
from .params import FmtImage, FmtParams
from .transforms import columns_fft, fft_workers, hann_window, rfft2_first, rows_fft, rows_then_columns

__all__ = ["prepare", "polar_spectrum", "folded_spectrum", "warm_up"]


_highpass: dict[int, np.ndarray] = {}
_tapers: dict[tuple, np.ndarray] = {}
_lowpass: dict[tuple, np.ndarray | None] = {}


def _high_pass(n: int) -> np.ndarray:
    """Reddy & Chatterji's high-pass (1 - X)(2 - X), X = cos(pi u) cos(pi v), centred spectrum."""
    if n not in _highpass:
        f = np.fft.fftshift(np.fft.fftfreq(n))
        x = np.outer(np.cos(np.pi * f), np.cos(np.pi * f))
        _highpass[n] = ((1.0 - x) * (2.0 - x)).astype(np.float32)
    return _highpass[n]


def _taper(p: FmtParams) -> np.ndarray:
    key = (p.size, p.cell_m, p.range_min_m, p.range_max_m, p.taper_m)
    if key not in _tapers:
        c = (np.arange(p.size) - p.size // 2) * p.cell_m
        r = np.hypot(c[None, :], c[:, None])
        r_max = p.range_max_m or p.size * p.cell_m / 2.0
        w = np.clip((r_max - r) / max(p.taper_m, 1e-9), 0.0, 1.0)
        w = 0.5 - 0.5 * np.cos(np.pi * w)
        w[r < p.range_min_m] = 0.0
        _tapers[key] = w.astype(np.float32)
    return _tapers[key]


def low_pass(n: int, cell_m: float, min_wavelength_m: float) -> np.ndarray | None:
    """Weight of the whitened cross-power spectrum (``rfft2`` layout of an n x n image): 1 up
    to half the cut-off frequency 1 / min_wavelength_m, a cosine roll-off to 0 at it; None
    when the cut-off is at or beyond Nyquist (the whole band, Algorithm 1 as written)."""
    key = (n, cell_m, min_wavelength_m)
    if key not in _lowpass:
        fc = cell_m / min_wavelength_m if min_wavelength_m > 0 else np.inf  # cycles / cell
        if fc >= 0.5 * math.sqrt(2):
            _lowpass[key] = None
        else:
            f = np.hypot(np.fft.fftfreq(n)[:, None], np.fft.rfftfreq(n)[None, :])
            u = np.clip((f - 0.5 * fc) / (0.5 * fc), 0.0, 1.0)
            _lowpass[key] = (0.5 + 0.5 * np.cos(np.pi * u)).astype(np.float32)
    return _lowpass[key]


def _resample(grid: Grid, p: FmtParams, pool: TaskPool | None = None) -> np.ndarray:
    """The grid's values on the registration grid (radar at cell size // 2, axes kept); ``pool``:
    the 2 x 2 mean and the warp in halves of rows on its threads (the same numbers)."""
    return _resample_parts(grid, p, pool)[0]


def _resample_parts(grid: Grid, p: FmtParams, pool: TaskPool | None = None,
                    then: Callable[[np.ndarray, int, int], Any] | None = None) -> tuple[np.ndarray, list]:
    """:func:`_resample`'s image and the list of ``then(image, r0, r1)`` on its rows r0..r1: with a pool, on
    each half of rows after that half's warp, on the pool's threads; without, once on the whole image (``then``
    None: an empty list)."""
    data = np.ascontiguousarray(grid.data, np.float32)
    s = grid.cell_m / p.cell_m
    # registration pixel = s * grid pixel + offset, the vehicle origin -> centre cell
    m = np.array([[s, 0.0, grid.origin_x_m / p.cell_m + p.size // 2],
                  [0.0, s, grid.origin_y_m / p.cell_m + p.size // 2]])
    interp = cv2.INTER_AREA if s < 1.0 else cv2.INTER_LINEAR
    if s < 1.0 and abs(1.0 / s - round(1.0 / s)) < 1e-6:  # integer reduction: average the cells
        k = int(round(1.0 / s))
        h, w = (data.shape[0] // k) * k, (data.shape[1] // k) * k
        if k == 2:  # the mean below, summed in numpy's order (bit-identical), in one compiled pass
            from ._jit import mean2x2

            src, data = data, np.empty((h // 2, w // 2), np.float32)  # ((x00 + x01) + (x10 + x11)) / 4
            _halves(pool, lambda r0, r1: mean2x2(src[2 * r0:2 * r1], data[r0:r1]), h // 2)
        else:
            data = data[:h, :w].reshape(h // k, k, w // k, k).mean(axis=(1, 3))
        m = np.array([[1.0, 0.0, (grid.origin_x_m + 0.5 * (k - 1) * grid.cell_m) / p.cell_m + p.size // 2],
                      [0.0, 1.0, (grid.origin_y_m + 0.5 * (k - 1) * grid.cell_m) / p.cell_m + p.size // 2]])
        # a shift only: warped in two halves of rows, with or without a pool (so the same numbers with 1 thread or
        # 2), each from its first row (the shift's row offset less r0). OpenCV computes the coordinates in float32:
        # the same numbers as the whole image's warp whenever the offsets less r0 are exact in float32, as the
        # panoramics' are (multiples of 1/4 cell: every RADIATE and campus grid checked)
        out = np.empty((p.size, p.size), data.dtype)

        def warp(r0: int, r1: int) -> Any:
            mr = m.copy()
            mr[1, 2] -= r0
            cv2.warpAffine(data, mr, (p.size, r1 - r0), dst=out[r0:r1], flags=cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            return then(out, r0, r1) if then is not None and pool is not None and pool.threads > 1 else None

        mid = p.size // 2
        if pool is not None and pool.threads > 1:
            return out, pool.map(warp, [(0, mid), (mid, p.size)])
        warp(0, mid)
        warp(mid, p.size)
        return out, [] if then is None else [then(out, 0, p.size)]
    img = cv2.warpAffine(data, m, (p.size, p.size), flags=interp, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return img, [] if then is None else _halves(pool, lambda r0, r1: then(img, r0, r1), p.size)


def warm_up() -> None:
    """Load the compiled loops (numba, from its cache) and scipy.fft now rather than in the first turn (a
    component's start(): the plugin's import, which every command pays, never imports scipy.fft)."""
    import scipy.fft  # noqa: F401 - the rotation's 1-D transforms

    from ._jit import mean2x2, pack_ccs, sum_sq

    mean2x2(np.zeros((2, 2), np.float32), np.empty((1, 1), np.float32))
    _threshold(np.ones((2, 2), np.float32), 0.5, True, np.ones((2, 2), np.float32), np.empty((2, 2), np.float32))
    pack_ccs(np.zeros((4, 3), np.complex64), np.empty((4, 4), np.float32))
    sum_sq(np.zeros((4, 3), np.complex64), 4)


def _threshold(img: np.ndarray, level: float, linear: bool, taper: np.ndarray, out: np.ndarray) -> bool:
    """Step 2 and the taper into ``out``, the same bits as numpy's ``keep = img > level; out = 0; out[keep] =
    10 log10(img[keep] / level)`` (``linear``; else ``img[keep] - level``) then ``out *= taper``: the cells kept
    listed in one compiled pass (those of a taper 0 left 0 without their logarithm), numpy's logarithm of them,
    the product with the taper written back in a second pass (numpy's formulation read and wrote the image five
    times; its masked gather and scatter were the costliest). Whether a cell is nonzero."""
    from ._jit import over_level, scatter_tapered

    idx = np.empty(img.size, np.intp)
    vals = np.empty(img.size, np.float32)
    k = over_level(img, level, linear, taper, out, idx, vals)
    db = 10.0 * np.log10(vals[:k]) if linear else vals[:k]
    return scatter_tapered(db, idx[:k], taper, out)


def _quantile(vals: np.ndarray, q: float) -> float:
    """``np.quantile(vals, q)`` (linear, the default method), the same number, ``vals`` reordered: the
    two order statistics it interpolates are selected among the values at or above a bound taken
    low on a sample (the exact ones whenever fewer values than the lower rank lie under it, else the
    whole array is partitioned as numpy does), then numpy interpolates them with the same weight
    (its virtual index (n - 1) q, here on two values: the same float64 fraction and formula)."""
    return _quantile_of([(vals, *_upper(vals, q))], q)


def _upper(vals: np.ndarray, q: float) -> tuple[float, np.ndarray]:
    """A bound well under the q-quantile of ``vals`` (taken on a sample; -inf for few values) and the
    values at or above it: :func:`_quantile_of`'s part of one piece of the values (each half of rows's
    on its own thread)."""
    if vals.size < 4096:
        return -math.inf, vals
    # a prime stride: 64 sampled the same few columns of every row, on RADIATE the half of rows' sample quantile
    # over the whole's
    sample = vals[::61].copy()
    j = max(int((q - 0.05) * (sample.size - 1)), 0)  # well under the sample's q-quantile (halves differ by 0.04)
    bound = float(np.partition(sample, j)[j])
    return bound, vals[vals >= bound]


def _quantile_of(parts: list[tuple[np.ndarray, float, np.ndarray]], q: float) -> float:
    """``np.quantile`` of the values of all ``parts``, each ``(values, bound, values at or above bound)``
    (:func:`_upper`): the order statistics selected among the parts' values at or above their own bounds, exact
    when the lower one is at or above every bound (else, and when too many values lie under the bounds,
    numpy's selection on all the values): the same number whatever the bounds."""
    n = sum(v.size for v, _, _ in parts)
    v = (n - 1) * q  # numpy's virtual index (float64), its floor and fraction
    k = int(math.floor(v))

    def numpys() -> float:
        vals = parts[0][0] if len(parts) == 1 else np.concatenate([p[0] for p in parts])
        return float(np.quantile(vals, q, overwrite_input=True))

    if n < 4096 or k + 1 >= n:
        return numpys()
    # each part's values at or above its own bound, as they are (not selected again over the largest bound:
    # 0.15-0.3 ms at 512 cells); the values left out, ``below`` of them, each under its part's bound
    bound = max(b for _, b, _ in parts)
    top = parts[0][2] if len(parts) == 1 else np.concatenate([t for _, _, t in parts])
    below = n - top.size
    if below > k:  # the bound was not under the k-th value: numpy's own selection
        return numpys()
    r = k - below  # the rank of the lower one among the values selected
    if top.size >= 4096:  # those around it on a sample of them: a window of a few % of them partitioned
        sample = top[::7].copy()
        f = r / top.size
        lo, hi = int(max(f - 0.04, 0.0) * (sample.size - 1)), int(min(f + 0.04, 1.0) * (sample.size - 1))
        sample.partition((lo, hi))
        window = top[(top >= sample[lo]) & (top <= sample[hi])]
        under = int(np.count_nonzero(top < sample[lo]))
        if 0 <= r - under and r - under + 1 < window.size:  # the two in the window: ranks r - under, + 1 in it
            top, r = window, r - under
    top.partition((r, r + 1))
    if top[r] < bound:  # a value left out (under its part's bound <= the largest) may lie over it: numpy's own
        return numpys()
    # every value left out lies under the largest bound <= top[r]: top[r] has k values under it in all, it is
    # the k-th, and top[r + 1] the next
    pair = np.array([top[r], top[r + 1]], parts[0][0].dtype)
    return float(np.quantile(pair, v - k, overwrite_input=True))


def prepare(grid: Grid, params: FmtParams | None = None, linear_power: bool = True, workers: int = 1,
            pool: TaskPool | None = None) -> FmtImage:
    """Steps 1-5 for one image: resample, threshold (step 2), dB, taper; polar |FFT|.

    ``linear_power``: the grid holds power (the panoramic builder); False if already in dB
    (Navtech PNGs). ``workers``: scipy.fft's threads for its transform; ``pool``: the element-wise
    steps in halves of rows on its threads (each cell computed alike: the same numbers)."""
    with fft_workers(workers):
        return _prepare(grid, params or FmtParams(), linear_power, pool)


def _halves(pool: TaskPool | None, fn: Callable[[int, int], Any], rows: int) -> list:
    """``fn(r0, r1)`` on the two halves of ``rows`` on the pool's threads (one call without a pool)."""
    if pool is None or pool.threads < 2:
        return [fn(0, rows)]
    h = rows // 2
    return pool.map(fn, [(0, h), (h, rows)])


def _prepare(grid: Grid, p: FmtParams, linear_power: bool, pool: TaskPool | None = None) -> FmtImage:
    def observed_of(img: np.ndarray, r0: int, r1: int) -> tuple[np.ndarray, float, np.ndarray, float]:
        part = img[r0:r1]
        vals = part[part > 0]
        return vals, *_upper(vals, p.db_floor_quantile), float(vals.max()) if vals.size else 0.0

    # the observed values (img[img > 0]), those over a bound under the threshold's quantile and their maximum, a
    # half of the rows each, after that half's warp (on the pool's threads)
    img, parts = _resample_parts(grid, p, pool, observed_of)
    observed = sum(v.size for v, _, _, _ in parts)
    n = img.shape[0]
    out = np.empty_like(img)  # every cell written by finish()
    hann = hann_window(out.shape)
    hi = int(p.band[1] * n)
    square = out.shape[1] == n and n % 2 == 0 and hi + 4 < n // 2  # the polar spectrum from the rfft2 kept
    windowed = np.empty_like(img) if square else None  # every cell written by finish(); only that path uses it
    level = math.inf  # nothing observed: every cell 0
    if observed:
        level = _quantile_of([part[:3] for part in parts], p.db_floor_quantile)  # the values: reordered
        if linear_power:
            level = max(level, max(m for _, _, _, m in parts) * 1e-12, np.finfo(np.float32).tiny)
    taper = _taper(p)
    lp = low_pass(n, p.cell_m, p.min_wavelength_m)
    cols, _ = spectrum_columns(out.shape, lp, True)
    width = max(cols, hi + 4)  # the windowed image's rfft2 columns kept

    def finish(r0: int, r1: int) -> tuple[np.ndarray | None, bool]:  # threshold, dB, taper and window of rows r0..r1
        # FmtImage.any_cell by halves, here rather than once per registration
        nonzero = _threshold(img[r0:r1], level, linear_power, taper[r0:r1], out[r0:r1])
        if windowed is None:
            return None, nonzero
        np.multiply(out[r0:r1], hann[r0:r1], out=windowed[r0:r1])
        # the first step of rows_then_columns(windowed, width): the transform of these rows, cv2.dft's (the same
        # numbers as the whole image's; 0.33 ms at 512 x 512 against 1.03 ms for scipy.fft's on one thread)
        return rows_fft(windowed[r0:r1], width), nonzero

    finished = _halves(pool, finish, n)
    nonzero = any(z for _, z in finished)
    rows = [r for r, _ in finished]
    if square:
        # the windowed image's rfft2 serves twice: the polar spectrum's magnitude and, when this
        # image is the older one of a pair, the translation's spectrum on the full grid (image_spectrum):
        # its rows transformed by halves beside the window above (cv2.dft), its columns here on scipy.fft's
        # workers (each column computed alike: the same numbers)
        rows = rows[0] if len(rows) == 1 else np.concatenate(rows)
        rf = columns_fft(rows)
        fi = FmtImage(out, np.empty((0, 0), np.float32), p.cell_m, {cols: np.ascontiguousarray(rf[:, :cols])},
                      nonzero=nonzero)
        if coarse_rows(n, lp, cols) is None:
            _polar_folded(fi, out, p, rf, pool)
            return fi
        # on the coarse grid, the spectrum this image will have as the older one of the next pair (its halved
        # image with it) beside its polar spectrum and the rotation's folded one (the same numbers as computed
        # then; here rather than beside the rotation)
        if pool:
            pool.map(call_with, [(_polar_folded, fi, out, p, rf), (image_spectrum, fi, cols, True)])
        else:
            _polar_folded(fi, out, p, rf)
            image_spectrum(fi, cols, True)
        return fi
    fi = FmtImage(out, np.empty((0, 0), np.float32), p.cell_m, nonzero=nonzero)
    _polar_folded(fi, out, p)
    return fi


def _polar_folded(fi: FmtImage, img: np.ndarray, p: FmtParams, rf: np.ndarray | None = None,
                  pool: TaskPool | None = None) -> None:
    """The image's polar spectrum (:func:`polar_spectrum`; ``pool``: its resampling by halves) and its folded
    transform (:func:`folded_spectrum`) into ``fi``."""
    fi.polar = polar_spectrum(img, p, rf, pool)
    folded_spectrum(fi, p.angles // 2)


def folded_spectrum(img: FmtImage, half: int) -> np.ndarray:
    """The rfft along the angles of the image's polar spectrum folded onto half a turn (the rotation's, steps 6-9):
    once per image (kept in :attr:`FmtImage.folded`), not once per registration it is in."""
    if img.folded is None or img.folded.shape[0] != half // 2 + 1:
        import scipy.fft

        img.folded = scipy.fft.rfft(img.polar[:half] + img.polar[half:2 * half], axis=0, workers=1)
    return img.folded


def polar_spectrum(img: np.ndarray, p: FmtParams, rf: np.ndarray | None = None,
                   pool: TaskPool | None = None) -> np.ndarray:
    """Steps 3-5: the high-passed |FFT| of the windowed image in polar coordinates over the band;
    ``rf``: the windowed image's rfft2 (its first columns, at least the band's radius + 4) if known;
    ``pool``: the polar resampling in halves of the angles on its threads (the same numbers)."""
    n = img.shape[0]
    radii = n // 2
    lo, hi = int(p.band[0] * n), int(p.band[1] * n)  # radius of f cycles/cell = f * n pixels
    flags = cv2.INTER_LINEAR + cv2.WARP_FILL_OUTLIERS + cv2.WARP_POLAR_LINEAR
    centre = (float(n // 2), float(n // 2))  # the DC bin
    if img.shape[1] == n and n % 2 == 0 and hi + 4 < radii:
        # only the radii up to the band's are resampled (one pixel per radius as over the whole
        # half side: the same numbers), from the spectrum within them
        m = hi + 4
        spec = _magnitude(img * hann_window(img.shape) if rf is None else None, m, rf, n)
        c = n // 2  # the high-pass on the square the warp reads (radius < hi, 2 x 2 neighbours): 0 beyond
        spec[c - m:c + m, c - m:c + m] *= _high_pass(n)[c - m:c + m, c - m:c + m]
        # cv2.warpPolar(spec, (hi, p.angles), centre, hi, flags) as its cv2.remap from its maps, kept (not computed
        # at every call) and read by halves of the angles
        mx, my = _polar_maps(hi, p.angles, centre)
        polar = np.empty((p.angles, hi), np.float32)

        def resample(r0: int, r1: int) -> None:
            cv2.remap(spec, mx[r0:r1], my[r0:r1], cv2.INTER_LINEAR, dst=polar[r0:r1], borderMode=cv2.BORDER_CONSTANT,
                      borderValue=0)

        _halves(pool, resample, p.angles)
    else:
        import scipy.fft

        spec = np.abs(scipy.fft.fftshift(scipy.fft.fft2(img * hann_window(img.shape), workers=1))).astype(np.float32)
        spec *= _high_pass(n)
        polar = cv2.warpPolar(spec, (radii, p.angles), centre, radii, flags)
    band = polar[:, lo:hi]
    return np.ascontiguousarray(band / max(float(band.std()), 1e-12), np.float32)


_polar_maps_of: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}


def _polar_maps(radii: int, angles: int, centre: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """The maps ``cv2.warpPolar`` computes for its remap (linear polar, ``radii`` pixels over the radius ``radii``,
    ``angles`` rows over a turn), as OpenCV computes them: x = rho / (width / max_radius) cos(phi 2 pi / height)
    + cx in float64, then float32 (its warpPolar and this remap: the same numbers on every RADIATE and campus image
    checked, tests/slam/test_fmt_core.py against cv2.warpPolar)."""
    key = (radii, angles, centre)
    if key not in _polar_maps_of:
        phi = np.arange(angles, dtype=np.float64)[:, None] * (2 * math.pi / angles)
        r = np.arange(radii, dtype=np.float64)[None, :] / (radii / float(radii))
        _polar_maps_of[key] = ((r * np.cos(phi) + centre[0]).astype(np.float32),
                               (r * np.sin(phi) + centre[1]).astype(np.float32))
    return _polar_maps_of[key]


def _magnitude(img: np.ndarray | None, m: int, rf: np.ndarray | None = None, n: int = 0) -> np.ndarray:
    """``abs(fftshift(fft2(img)))`` of a real n x n image (n even) within m rows and m columns of
    the DC bin (0 beyond), the same numbers from m columns of its rfft2: fft2 of a real image is its
    rfft2 with the other half (and the second half of column 0) filled by symmetry,
    F(-u, -v) = conj F(u, v). ``rf``: the image's rfft2 (at least m columns) if known."""
    if rf is None:
        n = img.shape[0]
        rf = rows_then_columns(img, m)  # as prepare() computes it
    a = np.abs(rf[:, :m])
    # written straight into fftshift's layout (row and column r -> (r + n/2) mod n), no roll:
    # columns 0..m-1, the second half of column 0, then columns n-m+1..n-1 by symmetry; the rows
    # h-m..h+m-1 only (frequencies -m..m-1)
    h = n // 2
    out = np.zeros((n, n), a.dtype)
    rows = np.arange(h - m, h + m)
    out[h - m:h + m, h:h + m] = a[(rows - h) % n]
    out[h - m:h, h] = a[m:0:-1, 0]  # the second half of column 0 (its row h: DC, set above)
    out[h - m:h + m, h - m + 1:h] = a[(h - rows) % n][:, m - 1:0:-1]
    return out


def call_with(fn: Callable[..., Any], *args: object) -> Any:
    return fn(*args)


def half_image(img: FmtImage) -> np.ndarray:
    """The image on the n/2 x n/2 grid (``cv2.pyrDown``: coarse cell i = fine cell 2 i, the centre kept)."""
    if img.half is None:
        img.half = cv2.pyrDown(img.image)
    return img.half


def image_spectrum(a: FmtImage, cols: int, coarse: bool) -> np.ndarray:
    """rfft2 of the older image (windowed), the columns the translation uses, on the full grid or
    the coarse one: computed once per image, not once per rotation tried."""
    spectra = a.half_spectra if coarse else a.spectra
    if cols not in spectra:
        img = half_image(a) if coarse else a.image
        spectra[cols] = rfft2_first(img * hann_window(img.shape), cols)
    return spectra[cols]
