"""The FMT's compiled loops (numba, ``cache=True``; imported at their first call, never with the
plugin): the 2 x 2 mean of a grid, the same bits as the numpy formulation it replaces
(``((x00 + x01) + (x10 + x11)) / 4`` in float32; tests/slam/test_fmt_core.py compares them); a spectrum
packed for ``cv2.dft``'s real inverse (OpenCV's CCS layout) and a spectrum's sum of squares (Parseval); the two
passes of a prepared image's threshold and taper around numpy's logarithm (the cells kept listed, then their tapered
dB written back)."""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["mean2x2", "over_level", "pack_ccs", "scatter_tapered", "sum_sq"]


@numba.njit(cache=True, nogil=True)
def mean2x2(data, out):  # pragma: no cover - compiled
    """out[i, j] = ((d[2i, 2j] + d[2i, 2j+1]) + (d[2i+1, 2j] + d[2i+1, 2j+1])) / 4 in float32, one pass
    (numpy's strided sums read the grid three times)."""
    four = np.float32(4)
    for i in range(out.shape[0]):
        r0 = data[2 * i]
        r1 = data[2 * i + 1]
        for j in range(out.shape[1]):
            out[i, j] = ((r0[2 * j] + r0[2 * j + 1]) + (r1[2 * j] + r1[2 * j + 1])) / four
    return out


@numba.njit(cache=True, nogil=True)
def pack_ccs(spec, out):  # pragma: no cover - compiled
    """OpenCV's packed layout (CCS) of an even rows x cols real image's spectrum (``cv2.dft``'s, the input of its
    real inverse) from its first columns in rfft2's layout (``spec``: rows x k, k <= cols / 2 + 1; the columns
    beyond are 0): columns 1 .. cols/2 - 1 as (re, im) pairs, columns 0 and cols/2 down the first and last
    columns (re of row 0, (re, im) of rows 1 .. rows/2 - 1, re of row rows/2). Returns the sum of |X|^2 over the
    whole rows x cols spectrum (Hermitian: the pair columns twice), float64: Parseval's sum of squares of the
    inverse times rows x cols."""
    rows, n = out.shape
    k = spec.shape[1]
    h = n // 2
    inner = min(k, h)
    s = 0.0
    for i in range(rows):
        for j in range(1, inner):
            z = spec[i, j]
            out[i, 2 * j - 1] = z.real
            out[i, 2 * j] = z.imag
            s += 2.0 * (float(z.real) * float(z.real) + float(z.imag) * float(z.imag))
        for j in range(max(2 * inner - 1, 1), n - 1):
            out[i, j] = 0
    half = rows // 2
    for c, col in ((0, 0), (h, n - 1)):
        if c < k:
            out[0, col] = spec[0, c].real
            for u in range(1, half):
                out[2 * u - 1, col] = spec[u, c].real
                out[2 * u, col] = spec[u, c].imag
            out[rows - 1, col] = spec[half, c].real
            for u in range(rows):
                z = spec[u, c]
                s += float(z.real) * float(z.real) + float(z.imag) * float(z.imag)
        else:
            for u in range(rows):
                out[u, col] = 0
    return s


@numba.njit(cache=True, nogil=True)
def sum_sq(spec, n):  # pragma: no cover - compiled
    """The sum of |X|^2 over the whole rows x n spectrum of a real image from its first columns in rfft2's
    layout (``spec``; the columns beyond are 0): column 0 once, and column n / 2 (n even) once, the others
    twice (Hermitian); float64 (:func:`pack_ccs`'s sum without the packing)."""
    rows, k = spec.shape
    s = 0.0
    for i in range(rows):
        for j in range(k):
            z = spec[i, j]
            a = float(z.real) * float(z.real) + float(z.imag) * float(z.imag)
            s += a if j == 0 or 2 * j == n else 2.0 * a
    return s


@numba.njit(cache=True, nogil=True)
def over_level(img, level, linear, taper, out, idx, vals):  # pragma: no cover - compiled
    """Step 2's first half in one pass: ``out`` set to 0, and the cells over ``level`` where the taper is not 0
    listed (flat index in ``idx``, ``img / level`` (``linear``) or ``img - level`` in ``vals``, float32 as numpy
    computes them with ``level`` a Python float). Returns how many."""
    lv = np.float32(level)
    cols = img.shape[1]
    k = 0
    for i in range(img.shape[0]):
        for j in range(cols):
            out[i, j] = 0
            v = img[i, j]
            if v > lv and taper[i, j] != 0:
                idx[k] = i * cols + j
                vals[k] = v / lv if linear else v - lv
                k += 1
    return k


@numba.njit(cache=True, nogil=True)
def scatter_tapered(db, idx, taper, out):  # pragma: no cover - compiled
    """``out.flat[idx] = db * taper.flat[idx]`` (float32); whether one is nonzero."""
    o, t = out.reshape(-1), taper.reshape(-1)
    nonzero = False
    for m in range(idx.size):
        v = db[m] * t[idx[m]]
        o[idx[m]] = v
        nonzero = nonzero or v != 0
    return nonzero
