"""Compiled lag terms of :func:`impala_radar.pairer.core.xcorr_speed_prior` (numba).

For each candidate speed and beam, the up/down cross-correlation read at the static offset
by linear interpolation: numpy built it in a dozen (speeds, beams) temporaries; here one
pass, the same float64 operations in the same order (no ``fastmath``), so the sums over the
beams (numpy's, left to it) and the chosen speed are the same bit for bit. Imported at first
use, compiled once per machine (``cache=True``).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["lag_terms"]


@numba.njit(cache=True, nogil=True)
def lag_terms(c, cos_az, speeds, scale, per, out):  # pragma: no cover - compiled
    """out[s, b] = (1 - w) c[b, i0] + w c[b, i0 + 1] (indices mod 2n, the row length), with
    lag = scale (-speeds[s] cos_az[b]) / per (``static_offset_bins``), i0 = floor(lag),
    w = lag - i0."""
    m = c.shape[1]
    for s in range(speeds.size):
        v = -speeds[s]
        for b in range(cos_az.size):
            lag = scale * (v * cos_az[b]) / per
            lo = np.floor(lag)
            w = lag - lo
            i0 = int(lo) % m
            i1 = i0 + 1
            if i1 == m:
                i1 = 0
            out[s, b] = (1 - w) * c[b, i0] + w * c[b, i1]
