"""Compiled ordered-statistic CFAR levels (numba) for :func:`impala_radar.peaks.find_os_peaks`.

The k-th smallest of the training cells of one bin, the value ``np.partition`` over the
sliding-window views of :func:`impala_radar.peaks.cfar_threshold` picks, computed only at the
bins that can be peaks (local maxima: a fifth of the bins or fewer) by an insertion sort of
their ``2 train`` cells. Imported by the first OS CFAR, compiled at its first call
(``cache=True``: once per machine, then loaded from numba's cache).
"""

from __future__ import annotations

import numba

__all__ = ["os_levels"]


@numba.njit(cache=True, nogil=True)
def os_levels(padded, train, guard, kk, beam, bin_, out):  # pragma: no cover - compiled
    """``out[j]`` the ``kk``-th smallest of ``padded[b, i:i + train]`` and
    ``padded[b, i + train + 2 guard + 1:][:train]``, (b, i) = (beam[j], bin_[j])."""
    gap = train + 2 * guard + 1
    buf = padded[0, :2 * train].copy()
    for j in range(beam.size):
        row = padded[beam[j]]
        i = bin_[j]
        for k in range(2 * train):  # insertion sort of the training cells
            v = row[i + k] if k < train else row[i + gap + k - train]
            m = k
            while m > 0 and buf[m - 1] > v:
                buf[m] = buf[m - 1]
                m -= 1
            buf[m] = v
        out[j] = buf[kk]
