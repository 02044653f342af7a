"""Compiled ordered-statistic CFAR peaks (numba) for :func:`impala_radar.peaks.find_os_peaks`.

One pass over the spectra: at each bin that can be a peak (a positive local maximum: a
fifth of the bins or fewer) the threshold test against the k-th smallest of its training cells,
the value ``np.partition`` over the sliding-window views of
:func:`impala_radar.peaks.cfar_threshold` picks, by counting the cells above the bin's power
over alpha (no sort, :func:`os_detects`). Imported by the first OS
CFAR, compiled at its first call (``cache=True``: once per machine, then loaded from numba's
cache).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["os_peaks"]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def os_detects(row, i, train, gap, n_top, p, alpha):  # pragma: no cover - compiled
    """``p > alpha * level``, level the smallest of the ``n_top`` largest of ``row[i:i + train]``
    and ``row[i + gap:][:train]`` (their ``2 train - n_top``-th smallest), without sorting: as
    x -> alpha x is non-decreasing, the cells with ``alpha x >= p`` are the largest ones, and
    the level is among them exactly when there are ``n_top`` or more."""
    count = 0
    for k in range(2 * train):
        x = row[i + k] if k < train else row[i + gap + k - train]
        if alpha * np.float64(x) >= p:
            count += 1
            if count == n_top:
                return False
    return True


@numba.njit(cache=True, nogil=True, error_model="numpy")
def os_peaks(power, padded, train, guard, kk, alpha, min_bin, nbh, beam, bin_):  # pragma: no cover - compiled
    """The (beam, bin) of ``find_peaks(power, cfar_threshold(power, ..., "os"), min_bin, nbh)``
    in its order, into ``beam``/``bin_``; returns how many. ``padded``: the float32 spectra
    mirrored by ``guard + train`` bins each side, whose OS level is tested only at the bins
    that are positive local maxima (+-``nbh`` bins, edges repeated)."""
    n_bins = power.shape[1]
    gap = train + 2 * guard + 1
    n_top = 2 * train - kk
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
            if peak and os_detects(padded[b], i, train, gap, n_top, np.float64(p), alpha):
                beam[count] = b
                bin_[count] = i
                count += 1
    return count
