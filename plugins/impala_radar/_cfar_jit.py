"""Compiled ordered-statistic CFAR (numba) for :func:`impala_radar.peaks.cfar_threshold`.

The k-th smallest of the training cells of each bin, the same value ``np.partition`` over
sliding-window views picks, from a sorted window that slides: each step one cell leaves and
one enters on each side (two ordered insertions into ``2 train`` sorted values instead of a
partition of them per bin). Imported by the first OS CFAR, compiled at its first call
(``cache=True``: once per machine, then loaded from numba's cache).
"""

from __future__ import annotations

import numba

__all__ = ["os_cfar"]


@numba.njit(cache=True, nogil=True)
def replace(buf, old, new):  # pragma: no cover - compiled
    """Sorted ``buf`` with one ``old`` value replaced by ``new``, kept sorted."""
    n = buf.size
    lo, hi = 0, n - 1
    while lo < hi:  # first index of old
        mid = (lo + hi) // 2
        if buf[mid] < old:
            lo = mid + 1
        else:
            hi = mid
    i = lo
    if new >= old:
        while i + 1 < n and buf[i + 1] < new:
            buf[i] = buf[i + 1]
            i += 1
    else:
        while i > 0 and buf[i - 1] > new:
            buf[i] = buf[i - 1]
            i -= 1
    buf[i] = new


@numba.njit(cache=True, nogil=True)
def os_cfar(padded, train, guard, kk, out):  # pragma: no cover - compiled
    """``out[b, i]`` the ``kk``-th smallest of ``padded[b, i:i + train]`` and
    ``padded[b, i + train + 2 guard + 1:][:train]``."""
    n_bins = out.shape[1]
    gap = train + 2 * guard + 1
    buf = padded[0, :2 * train].copy()
    for b in range(padded.shape[0]):
        row = padded[b]
        for j in range(train):
            buf[j] = row[j]
            buf[train + j] = row[gap + j]
        buf.sort()
        out[b, 0] = buf[kk]
        for i in range(1, n_bins):
            replace(buf, row[i - 1], row[i - 1 + train])
            replace(buf, row[i - 1 + gap], row[i - 1 + gap + train])
            out[b, i] = buf[kk]
