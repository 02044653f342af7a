"""Compiled ordered-statistic CFAR levels (numba) for :func:`impala_radar.peaks.find_os_peaks`.

The k-th smallest of the training cells of one bin, the value ``np.partition`` over the
sliding-window views of :func:`impala_radar.peaks.cfar_threshold` picks, computed only at the
bins that can be peaks (local maxima: a fifth of the bins or fewer), keeping only the
``2 train - k`` largest of their cells. Imported by the first OS CFAR, compiled at its first call
(``cache=True``: once per machine, then loaded from numba's cache).
"""

from __future__ import annotations

import numba

__all__ = ["os_levels"]


@numba.njit(cache=True, nogil=True)
def os_levels(padded, train, guard, kk, beam, bin_, out):  # pragma: no cover - compiled
    """``out[j]`` the ``kk``-th smallest of ``padded[b, i:i + train]`` and
    ``padded[b, i + train + 2 guard + 1:][:train]``, (b, i) = (beam[j], bin_[j]): the smallest
    of the ``2 train - kk`` largest, kept sorted while the cells stream by."""
    gap = train + 2 * guard + 1
    n_top = 2 * train - kk
    top = padded[0, :n_top].copy()  # ascending: top[0] is the answer once the cells are seen
    for j in range(beam.size):
        row = padded[beam[j]]
        i = bin_[j]
        count = 0
        for k in range(2 * train):
            v = row[i + k] if k < train else row[i + gap + k - train]
            if count < n_top:  # insertion while the buffer fills
                m = count
                while m > 0 and top[m - 1] > v:
                    top[m] = top[m - 1]
                    m -= 1
                top[m] = v
                count += 1
            elif v > top[0]:  # drop the smallest, insert v
                m = 0
                while m + 1 < n_top and top[m + 1] < v:
                    top[m] = top[m + 1]
                    m += 1
                top[m] = v
        out[j] = top[0]
