"""Compiled ordered-statistic CFAR peaks (numba) for :func:`impala_radar.peaks.find_os_peaks`.

One pass over the spectra: at each bin that can be a peak (a positive local maximum: a
fifth of the bins or fewer) the k-th smallest of its training cells, the value ``np.partition``
over the sliding-window views of :func:`impala_radar.peaks.cfar_threshold` picks, keeping only
the ``2 train - k`` largest of the cells, then the threshold test. Imported by the first OS
CFAR, compiled at its first call (``cache=True``: once per machine, then loaded from numba's
cache).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["os_peaks"]


@numba.njit(cache=True, nogil=True)
def os_level(row, i, train, gap, n_top, top):  # pragma: no cover - compiled
    """The smallest of the ``n_top`` largest of ``row[i:i + train]`` and ``row[i + gap:][:train]``
    (kept sorted in ``top`` while the cells stream by): their ``2 train - n_top``-th smallest."""
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
    return top[0]


@numba.njit(cache=True, nogil=True)
def os_peaks(power, padded, train, guard, kk, alpha, min_bin, nbh, beam, bin_):  # pragma: no cover - compiled
    """The (beam, bin) of ``find_peaks(power, cfar_threshold(power, ..., "os"), min_bin, nbh)``
    in its order, into ``beam``/``bin_``; returns how many. ``padded``: the float32 spectra
    mirrored by ``guard + train`` bins each side, whose OS level is computed only at the bins
    that are positive local maxima (+-``nbh`` bins, edges repeated)."""
    n_bins = power.shape[1]
    gap = train + 2 * guard + 1
    n_top = 2 * train - kk
    top = padded[0, :n_top].copy()
    count = 0
    for b in range(power.shape[0]):
        row = power[b]
        for i in range(max(min_bin, 1), n_bins - 1):
            p = row[i]
            if not p > 0:
                continue
            peak = True
            for j in range(i - nbh, i + nbh + 1):
                if row[min(max(j, 0), n_bins - 1)] > p:
                    peak = False
                    break
            if not peak:
                continue
            level = os_level(padded[b], i, train, gap, n_top, top)
            if np.float64(p) > alpha * np.float64(level):
                beam[count] = b
                bin_[count] = i
                count += 1
    return count
