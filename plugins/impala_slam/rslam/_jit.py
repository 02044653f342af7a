"""R-SLAM's compiled loops (numba, ``cache=True``, nogil; imported by ``RSlam.start()`` or at the
first map update or read, never with the plugin), each one pass: the merge of a turn into a map
tile (eq. 6), the read of a tile's weighted mean, the end of
:func:`~impala_slam.rslam.matching.contrast`. They give the bits of the numpy formulations they
replace (alpha zeroed where the amplitude is NaN, alpha A, a masked add and the normaliser's
add; a masked division and the support; a masked division, a difference and a product;
tests/slam/test_rslam_threads.py compares them)."""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["contrast_tail", "merge_tile", "mean_tile"]


# one signature each, any-layout float32 images (views of tiles and windows are C-contiguous or not
# by chance): compiled or loaded from the cache once, when this module is imported (RSlam.start),
# never again at a turn
_IMG = numba.float32[:, :]


@numba.njit(numba.boolean(_IMG, _IMG, _IMG, _IMG, numba.boolean), cache=True, nogil=True)
def merge_tile(amp, alpha, ws, cnt, weighted):  # pragma: no cover - compiled
    """Where alpha > 0 and ``amp`` is a number: ``ws += alpha * amp`` and ``cnt += alpha``
    (``weighted``) or ``cnt += 1``; float32 throughout (the same roundings as numpy's float32
    ufuncs). Returns whether any cell was merged."""
    touched = False
    one = np.float32(1.0)
    for i in range(amp.shape[0]):
        a_row, w_row, s_row, c_row = amp[i], alpha[i], ws[i], cnt[i]
        for j in range(amp.shape[1]):
            w = w_row[j]
            v = a_row[j]
            if w > 0 and v == v:
                s_row[j] += w * v
                c_row[j] += w if weighted else one
                touched = True
    return touched


@numba.njit(numba.void(_IMG, _IMG, _IMG, _IMG), cache=True, nogil=True)
def mean_tile(ws, cnt, out, support):  # pragma: no cover - compiled
    """Where ``cnt`` > 0: ``out = ws / cnt`` (float32) and ``support = 1``; elsewhere both are
    left as they are (the caller's zeros)."""
    one = np.float32(1.0)
    for i in range(ws.shape[0]):
        s_row, c_row, o_row, p_row = ws[i], cnt[i], out[i], support[i]
        for j in range(ws.shape[1]):
            c = c_row[j]
            if c > 0:
                o_row[j] = s_row[j] / c
                p_row[j] = one


@numba.njit(numba.void(_IMG, _IMG, _IMG, _IMG), cache=True, nogil=True)
def contrast_tail(img, mean, weight, support):  # pragma: no cover - compiled
    """In place in ``mean``: ``(img - mean / weight) * support``, the division only where
    weight > 1e-3 (float32, as NumPy 2 compares a float32 array with a Python float)."""
    eps = np.float32(1e-3)
    for i in range(img.shape[0]):
        g_row, m_row, w_row, s_row = img[i], mean[i], weight[i], support[i]
        for j in range(img.shape[1]):
            m = m_row[j]
            w = w_row[j]
            if w > eps:
                m = m / w
            m_row[j] = (g_row[j] - m) * s_row[j]
