"""Compiled per-cell loops of :func:`impala_radar.panoramic.core.scan_to_grid` (numba).

Each loop fuses what numpy would do in a dozen passes over the grid (gathers by beam,
differences, products) into one, with the same float32 operations in the same order, so
the grid is bit for bit the numpy formula's (no ``fastmath``: no reassociation, no fused
multiply-add). Imported by the first :func:`scan_to_grid`, compiled at its first call
(``cache=True``: once per machine, then loaded from numba's cache).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["rotate", "maps"]


@numba.njit(cache=True, nogil=True)
def rotate(x, y, i0, px, py, ct, st, u, v):  # pragma: no cover - compiled
    """u, v = R(-phi_i) (c - t_i) of every cell c, i = i0[c] its nominal beam."""
    xf, yf, kf, uf, vf = x.ravel(), y.ravel(), i0.ravel(), u.ravel(), v.ravel()
    for k in range(xf.size):
        i = kf[k]
        dx = xf[k] - px[i]
        dy = yf[k] - py[i]
        c, s = ct[i], st[i]
        a = c * dx
        b = s * dy
        uf[k] = a + b
        a = c * dy
        b = s * dx
        vf[k] = a - b


@numba.njit(cache=True, nogil=True)
def maps(r_read, r, r_cell, bearing, first_rad, per_rad, two_pi, offset_m, per_bin, r_max, r_min,
         uniform, map_x, map_y):  # pragma: no cover - compiled
    """map_x = (r_read - offset) per_bin, or -10 (outside the polar image: the remap
    reads 0 there) where the cell is off the disk or was nearer than r_min; with a
    uniform azimuth table map_y = mod(bearing - first, 2 pi) per_rad + 1 (else the
    caller's)."""
    rr, rf, rc, bf = r_read.ravel(), r.ravel(), r_cell.ravel(), bearing.ravel()
    mx, my = map_x.ravel(), map_y.ravel()
    one = np.float32(1.0)
    for k in range(rf.size):
        if rc[k] > r_max or rf[k] < r_min:
            mx[k] = np.float32(-10.0)
        else:
            mx[k] = (rr[k] - offset_m) * per_bin
        if uniform:
            d = bf[k] - first_rad
            if d >= two_pi:
                d = d - two_pi
            elif d < 0:
                d = d + two_pi
            my[k] = d * per_rad + one


@numba.njit(cache=True, nogil=True)
def doppler_mean(up, down, shift_bins, out):  # pragma: no cover - compiled
    """out[b, k] = 0.5 (up[b, k + s_b] + down[b, k - s_b]), each read by linear interpolation
    (0 outside), in float32 as :func:`impala_radar.panoramic.core._shift_rows` computes it."""
    n = up.shape[1]
    one, half = np.float32(1.0), np.float32(0.5)
    for b in range(up.shape[0]):
        for side in range(2):
            p = up[b] if side == 0 else down[b]
            s = shift_bins[b] if side == 0 else -shift_bins[b]
            for k in range(n):
                x = k + s
                k0f = np.floor(x)
                w = np.float32(x - k0f)
                k0 = int(k0f)
                lo = p[k0] if 0 <= k0 < n else np.float32(0.0)
                hi = p[k0 + 1] if 0 <= k0 + 1 < n else np.float32(0.0)
                v = (one - w) * lo + w * hi
                if side == 0:
                    out[b, k] = v
                else:
                    out[b, k] = half * (out[b, k] + v)
