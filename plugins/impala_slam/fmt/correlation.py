"""The FMT's phase correlation (steps 10-14 of :mod:`impala_slam.fmt.core`): the whitened cross-power spectrum,
the surface's peak, its sub-cell fit, Hessian and SNR, on the full grid or the coarse one."""

from __future__ import annotations

import math

import cv2
import numpy as np

from .transforms import irfft2_sums, rfft2_first

__all__ = ["phase_correlation"]


def _quadratic_peak(c: np.ndarray, iy: int, ix: int) -> tuple[float, float, np.ndarray]:
    """Sub-cell peak of a periodic surface by the quadratic through the 3x3 cells around
    (iy, ix): offsets (dy, dx) and the 2x2 Hessian of -c / c(peak) (1 / cells^2)."""
    ny, nx = c.shape
    w = np.array([[c[(iy + a) % ny, (ix + b) % nx] for b in (-1, 0, 1)] for a in (-1, 0, 1)], float)
    c0 = max(w[1, 1], 1e-12)
    gx = (w[1, 2] - w[1, 0]) / 2.0
    gy = (w[2, 1] - w[0, 1]) / 2.0
    hxx = w[1, 2] - 2 * w[1, 1] + w[1, 0]
    hyy = w[2, 1] - 2 * w[1, 1] + w[0, 1]
    hxy = (w[2, 2] - w[2, 0] - w[0, 2] + w[0, 0]) / 4.0
    h = -np.array([[hyy, hxy], [hxy, hxx]])
    try:
        d = np.linalg.solve(h, np.array([gy, gx]))
    except np.linalg.LinAlgError:
        d = np.zeros(2)
    if not np.all(np.isfinite(d)) or np.any(np.abs(d) > 1.0):
        d = np.zeros(2)
    return float(d[0]), float(d[1]), h / c0


def phase_correlation(a: np.ndarray, b: np.ndarray,
                      weight: np.ndarray | None = None) -> tuple[float, float, float, np.ndarray]:
    """Shift (dy, dx) in cells such that b(q) = a(q - d), its peak SNR and the normalised
    Hessian of the peak (eq. 1 of seed 2: normalised cross-power spectrum, inverse FFT)."""
    cols, w = spectrum_columns(a.shape, weight)
    return surface_peak(*correlate_sums(rfft2_first(a, cols), rfft2_first(b, cols), w, a.shape))


def spectrum_columns(shape: tuple[int, ...], weight: np.ndarray | None,
                     cache: bool = False) -> tuple[int, np.ndarray | None]:
    """Columns of the rfft2 layout the correlation needs (those where the weight is not 0, all
    without a weight) and the weight on them; ``cache``: the weight is one of :func:`low_pass`'s
    (kept for the process's life, so its id names it)."""
    if weight is None:
        return shape[1] // 2 + 1, None
    key = (id(weight), weight.shape)
    if cache and key in _columns_of:
        return _columns_of[key]
    nz = np.any(weight != 0, axis=0)
    cols = int(np.flatnonzero(nz)[-1]) + 1 if np.any(nz) else 1
    out = cols, np.ascontiguousarray(weight[:, :cols])
    if cache:
        _columns_of[key] = out
    return out


_columns_of: dict[tuple, tuple[int, np.ndarray]] = {}


_ELIDE_BYTES = 256 * 1024  # numpy's NPY_MIN_ELIDE_BYTES


def _whitened(fa: np.ndarray, fb: np.ndarray, weight: np.ndarray | None) -> np.ndarray:
    """The normalised cross-power spectrum of eq. 1 (seed 2), times ``weight`` when given, on this thread. (In
    halves of rows on a pool's threads, the fourth round's, it took 0.97 ms against 0.28 ms whole at 256 x 128
    coefficients and 1.5 against 0.66 ms at 400 x 201 on a loaded 2-core host: the two hand-offs cost more than
    a half saves.)"""
    # numpy computes fb * conj(fa) as conj(fa) * fb written over conj(fa)'s temporary when that holds at least
    # NPY_MIN_ELIDE_BYTES (its temporary elision), into a new array otherwise, and the two can differ in the
    # last bit: the same choice made here explicitly
    if fa.nbytes >= _ELIDE_BYTES and fa.shape == fb.shape:
        cross = np.conj(fa)
        np.multiply(cross, fb, out=cross)  # the elided product's operands: the temporary first
    else:
        cross = fb * np.conj(fa)
    mag = np.abs(cross)
    top = float(mag.max()) if mag.size else 0.0
    np.maximum(mag, mag.dtype.type(1e-12 * max(top, 1e-30)), out=mag)
    # times a real factor (weight / |cross|), not a complex division
    cross *= np.divide(weight, mag, out=mag) if weight is not None else np.reciprocal(mag, out=mag)
    return cross


def _correlate(fa: np.ndarray, fb: np.ndarray, weight: np.ndarray | None, shape: tuple[int, ...]) -> np.ndarray:
    """The phase correlation surface from two images' (first columns of) rfft2: the whitened
    cross-power spectrum, weighted, transformed back (the columns left out are zero). The
    surface over the whole spectrum to float32 rounding: numpy's complex64 product of the same
    numbers can differ in the last bit with the arrays' sizes (every registration of the
    512-cell RADIATE turns came out bit-identical; tests/slam/test_fmt_core.py)."""
    return correlate_sums(fa, fb, weight, shape)[0]


def correlate_sums(fa: np.ndarray, fb: np.ndarray, weight: np.ndarray | None,
                   shape: tuple[int, ...]) -> tuple[np.ndarray, tuple[float, float]]:
    """:func:`_correlate`'s surface and its sum and sum of squares, from the spectrum (its DC term, and
    Parseval: sum c^2 = sum |X|^2 / size), for :func:`surface_peak`'s SNR without another pass over the surface."""
    cross = _whitened(fa, fb, weight)
    c, s2 = irfft2_sums(cross, (shape[0], shape[1]))
    return c, (float(cross[0, 0].real), s2 / (shape[0] * shape[1]))


def surface_peak(c: np.ndarray, sums: tuple[float, float] | None = None) -> tuple[float, float, float, np.ndarray]:
    """The correlation surface's peak: shift (dy, dx) in cells, SNR, normalised Hessian; ``sums``: the
    surface's sum and sum of squares if known (:func:`correlate_sums`)."""
    iy, ix = np.unravel_index(int(np.argmax(c)), c.shape)
    dy, dx, h = _quadratic_peak(c, int(iy), int(ix))
    snr = _snr_sums(c, int(iy), int(ix), sums=sums)
    ny, nx = c.shape
    sy = (iy + dy + ny / 2) % ny - ny / 2
    sx = (ix + dx + nx / 2) % nx - nx / 2
    return float(sy), float(sx), snr, h


def masked_snr(c: np.ndarray, iy: int, ix: int, guard: int = 3) -> float:
    """Peak height over the standard deviation of the surface away from the peak."""
    ny, nx = c.shape
    rows = np.arange(iy - guard, iy + guard + 1) % ny
    cols = np.arange(ix - guard, ix + guard + 1) % nx
    if 2 * guard + 1 >= min(ny, nx):  # the window wraps onto itself: the mask, plainly
        mask = np.ones(c.shape, bool)
        mask[np.ix_(rows, cols)] = False
        rest = c[mask]
    else:
        rest = _outside(c, rows, cols)
    if rest.size == 0:
        return 0.0
    # rest.mean() and rest.std() as numpy computes them (the same sums and roundings: the sum
    # divided by the count in float64, rounded to the array's type), the mean summed once
    t, n = rest.dtype.type, np.intp(rest.size)
    mean = t(rest.sum() / n)
    dev = rest - mean
    np.multiply(dev, dev, out=dev)
    sd = float(t(np.sqrt(t(dev.sum() / n))))
    return float((c[iy, ix] - mean) / sd) if sd > 0 else 0.0


def _snr_sums(c: np.ndarray, iy: int, ix: int, guard: int = 3, sums: tuple[float, float] | None = None) -> float:
    """:func:`masked_snr` from the whole surface's sum and sum of squares (``sums`` if given, else
    ``cv2.meanStdDev``'s, in float64) less the window's: the same figure to float rounding, without
    copying the surface."""
    ny, nx = c.shape
    if 2 * guard + 1 >= min(ny, nx):
        return masked_snr(c, iy, ix, guard)
    w = c[np.ix_(np.arange(iy - guard, iy + guard + 1) % ny, np.arange(ix - guard, ix + guard + 1) % nx)]
    n_all = c.size
    if sums is None:
        m, sd = cv2.meanStdDev(c)
        s_all = float(m[0, 0]) * n_all
        q_all = (float(sd[0, 0]) ** 2 + float(m[0, 0]) ** 2) * n_all
    else:
        s_all, q_all = sums
    w = w.astype(np.float64)
    count = n_all - w.size
    mean = (s_all - float(w.sum())) / count
    var = max((q_all - float(np.square(w).sum())) / count - mean * mean, 0.0)
    return float((c[iy, ix] - mean) / math.sqrt(var)) if var > 0 else 0.0


def _outside(c: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``c[mask]`` (row-major order) for the mask that is False on rows x cols: the rows
    outside whole, each window row without its columns."""
    keep_cols = np.ones(c.shape[1], bool)
    keep_cols[cols] = False
    in_rows = np.zeros(c.shape[0], bool)
    in_rows[rows] = True
    pieces = []
    y = 0
    for r in np.flatnonzero(in_rows):
        if r > y:
            pieces.append(c[y:r].ravel())
        pieces.append(c[r, keep_cols])
        y = r + 1
    if y < c.shape[0]:
        pieces.append(c[y:].ravel())
    return np.concatenate(pieces)


_coarse_of: dict[tuple, np.ndarray | None] = {}


def coarse_rows(n: int, weight: np.ndarray | None, cols: int) -> np.ndarray | None:
    """Rows of the rfft2 layout (n x n image) kept on the coarse grid (:func:`coarse_peak`):
    those of frequency |f| < 1 / (2 k) cycles / cell, k = 2 (the coarse grid of n / 2 cells of
    2 cells each), when the low-pass is 0 at every frequency beyond (None otherwise: the
    whole grid, as without a low-pass)."""
    if weight is None or n % 4:
        return None
    key = (id(weight), n, cols)
    if key not in _coarse_of:
        m = n // 2
        rows = np.r_[0:m // 2, n - m // 2:n]
        outside = np.ones(n, bool)
        outside[rows] = False
        outside[n - m // 2] = True  # the coarse grid's Nyquist row: 0 too (no aliasing of the surface's energy)
        ok = cols <= m // 2 and not np.any(weight[outside]) and not np.any(weight[:, m // 2:])
        _coarse_of[key] = rows if ok else None
    return _coarse_of[key]


def coarse_peak(fa: np.ndarray, fb: np.ndarray, weight: np.ndarray, n: int,
                fit: bool = True) -> tuple[float, float, float, np.ndarray]:
    """:func:`surface_peak` of :func:`_correlate`'s n x n surface from the rows and columns of the
    spectra where the low-pass is not 0 (|f| < 1/4 cycle / cell on both axes), without the
    n x n surface. Why nothing is lost: the surface is the inverse transform of a spectrum
    that is 0 beyond 1/4 cycle per cell (the low-pass removes every wavelength shorter than
    min_wavelength_m >= 4 cells), so it is band-limited and its values every other cell (the
    inverse transform of the same coefficients on an n/2 x n/2 grid: Nyquist) hold all of
    it: the maximum is found on that coarse grid, then the surface's exact values on the 7 x 7
    cells around the full grid's maximum (the same sum of coefficients, evaluated at these
    cells) give the same quadratic peak and Hessian as :func:`surface_peak`, and its SNR's mean and
    standard deviation away from the peak come from the coarse grid's sums (the full grid's
    sum and sum of squares are 4 times theirs, Parseval on each of the 4 interleaved grids)
    less the 7 x 7 window's. The same figures to float rounding; on RADIATE turns at
    0.2 m cells, min_wavelength_m 0.8 m, 4x smaller inverse transforms and peak searches.
    ``fit`` False: the SNR alone (no sub-cell fit; the shift and Hessian returned are NaN)."""
    cross = _whitened(fa, fb, weight)
    m = n // 2
    c, s2 = irfft2_sums(cross, (m, m))  # = 4 x the n x n surface every other cell
    iy, ix = np.unravel_index(int(np.argmax(c)), c.shape)
    row_k, col_k, col_w, roots = _window_freqs(n, cross.shape[1])

    def window(y: int, x: int, r: int) -> np.ndarray:  # the n x n surface on the cells (y, x) +- r
        off = np.arange(-r, r + 1)  # exp(2 pi i k y / n) from the table of the n-th roots of unity
        # in complex64, as the spectrum is (sums of 10^4 terms: 1e-6 of the surface's largest values)
        w = (roots[np.outer(off + y, row_k) % n] @ cross @ (roots[np.outer(col_k, off + x) % n] * col_w)).real
        return w.astype(np.float64)

    y, x = 2 * int(iy), 2 * int(ix)
    w = window(y, x, 4)
    j, i = np.unravel_index(int(np.argmax(w)), w.shape)
    for _ in range(4):  # the full grid's maximum next to the coarse one's (nearly always within one cell)
        if abs(j - 4) <= 1 and abs(i - 4) <= 1:
            y, x = y + j - 4, x + i - 4
            w = w[j - 3:j + 4, i - 3:i + 4]
            break
        y, x = (y + j - 4) % n, (x + i - 4) % n
        w = window(y, x, 4)
        j, i = np.unravel_index(int(np.argmax(w)), w.shape)
    else:
        w = window(y, x, 3)
    # fit=False: the SNR only (the coarse search's)
    dy, dx, h = _quadratic_peak(w, 3, 3) if fit else (math.nan, math.nan, np.full((2, 2), math.nan))
    # the n x n surface's sum and sum of squares from its spectrum: the DC term, and Parseval (the same
    # coefficients on the n x n grid: sum c^2 = sum |X|^2 / n^2)
    s_all = float(cross[0, 0].real)
    q_all = s2 / (n * n)
    count = n * n - w.size
    mean = (s_all - float(w.sum())) / count
    var = max((q_all - float(np.square(w).sum())) / count - mean * mean, 0.0)
    sd = math.sqrt(var)
    snr = float((w[3, 3] - mean) / sd) if sd > 0 else 0.0
    sy = (y + dy + n / 2) % n - n / 2
    sx = (x + dx + n / 2) % n - n / 2
    return float(sy), float(sx), snr, h


_freqs_of: dict[tuple[int, int], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}


def _window_freqs(n: int, cols: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`coarse_peak`'s kept rows' and columns' frequencies (cycles per n cells), the columns'
    weights (Hermitian half: twice each column but DC; 1 / n^2 of the inverse DFT) and the n-th roots of
    unity exp(2 pi i j / n) (a table: no complex exponential per coefficient and window)."""
    if (n, cols) not in _freqs_of:
        m = n // 2
        _freqs_of[n, cols] = (np.r_[0:m // 2, -(m // 2):0], np.arange(cols),
                              (np.where(np.arange(cols) == 0, 1.0, 2.0) / (n * n))[:, None].astype(np.float32),
                              np.exp(np.arange(n) * (2j * np.pi / n)).astype(np.complex64))
    return _freqs_of[n, cols]
