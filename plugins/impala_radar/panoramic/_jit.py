"""Compiled per-cell loops of :func:`impala_radar.panoramic.core.scan_to_grid` (numba).

One loop moves each disk cell into its beam's frame and takes its range and bearing
(:func:`polar_cells`), one reads the polar image there by bilinear interpolation
(:func:`read_cells`): what numpy and OpenCV did in a dozen passes over the square (gathers by
beam, rotation, ``cv2.cartToPolar``, the maps, ``cv2.remap``), over the disk's cells only.
The float32 operations are OpenCV's and numpy's in the same order, so the grid is theirs bit
for bit: no ``fastmath`` (no reassociation), and a fused multiply-add exactly where OpenCV's
vector loops use one (``v_fma``/``v_muladd``, an FMA instruction on the machines OpenCV
dispatches AVX2 code to; tests/frontend/test_panoramic.py checks both against OpenCV).
Imported by the first :func:`scan_to_grid`, compiled at its first call (``cache=True``: once
per machine, then loaded from numba's cache).
"""

from __future__ import annotations

import numba
import numpy as np
from numba.core.extending import intrinsic

__all__ = ["polar_cells", "pad_polar", "read_cells", "doppler_mean"]


@intrinsic
def _fma(typingctx, a, b, c):
    """a b + c rounded once (float32), as OpenCV's ``v_fma`` / ``v_muladd`` compute it on an
    FMA machine (numba itself never fuses: no ``fastmath``)."""
    def codegen(context, builder, signature, args):
        return builder.fma(*args)
    return a(a, a, a), codegen


@numba.njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _atan_deg(y, x, p1, p3, p5, p7):  # pragma: no cover - compiled
    """OpenCV's ``v_atan_f32`` (``cv2.cartToPolar``'s angle, degrees in [0, 360]), op for op."""
    ax, ay = abs(x), abs(y)
    c = min(ax, ay) / (max(ax, ay) + np.float32(2.220446049250313e-16))  # + (float)DBL_EPSILON
    cc = c * c
    a = _fma(_fma(_fma(cc, p7, p5), cc, p3), cc, p1) * c
    a = a if ax >= ay else np.float32(90.0) - a
    a = np.float32(180.0) - a if x < np.float32(0.0) else a
    return np.float32(360.0) - a if y < np.float32(0.0) else a


# error_model="numpy": no ZeroDivisionError test in the loops (it kept them from being vectorised);
# each loop gathers a grid row's per-beam values into row buffers first, then computes the row in a
# loop of contiguous arrays the compiler vectorises (OpenCV's loops are vectorised too: same ops per lane)

@numba.njit(cache=True, nogil=True, error_model="numpy")
def polar_cells(c, spans, i0, px, py, ct, st, atan_p, uniform, first_rad, per_rad, two_pi,
                j0, j1, k0, r_out, row_out):  # pragma: no cover - compiled
    """Each disk cell of grid rows j0 to j1 - 1 moved into the frame of its nominal beam
    i = i0[cell], (u, v) = R(-phi_i) (cell - t_i), then its range and bearing as
    ``cv2.cartToPolar(u, v)`` gives them (bit for bit), packed row by row over ``spans`` (row j:
    columns spans[j, 0] to spans[j, 1] - 1; cell (j, k) is at x = c[k], y = c[j]), row j0's
    first cell at packed index k0. ``row_out``: with a uniform azimuth table the fractional row
    mod(bearing - first, 2 pi) per_rad + 1, else the bearing. Bands of rows are independent:
    threads may compute them at once (nogil), each cell the same whichever band holds it."""
    p1, p3, p5, p7, scale = atan_p[0], atan_p[1], atan_p[2], atan_p[3], atan_p[4]
    one, zero = np.float32(1.0), np.float32(0.0)
    m = c.size
    bdx, bdy = np.empty(m, np.float32), np.empty(m, np.float32)
    bc, bs = np.empty(m, np.float32), np.empty(m, np.float32)
    k = k0
    for j in range(j0, j1):
        yj = c[j]
        lo = spans[j, 0]
        n = spans[j, 1] - lo
        ij, cj = i0[j, lo:lo + n], c[lo:lo + n]
        for t in range(n):
            i = ij[t]
            bdx[t] = cj[t] - px[i]
            bdy[t] = yj - py[i]
            bc[t] = ct[i]
            bs[t] = st[i]
        ro, wo = r_out[k:k + n], row_out[k:k + n]
        for t in range(n):
            dx, dy, cs, sn = bdx[t], bdy[t], bc[t], bs[t]
            a = cs * dx
            b = sn * dy
            u = a + b
            a = cs * dy
            b = sn * dx
            v = a - b
            ro[t] = np.sqrt(_fma(u, u, v * v))
            bearing = _atan_deg(v, u, p1, p3, p5, p7) * scale
            d = bearing - first_rad
            d = d - two_pi if d >= two_pi else (d + two_pi if d < zero else d)
            wo[t] = d * per_rad + one if uniform else bearing
        k += n


@numba.njit(cache=True, nogil=True)
def pad_polar(power, order):  # pragma: no cover - compiled
    """The polar image (``power``'s beams in azimuth ``order`` with a wrap row each side, as
    :meth:`AzimuthTable.rows`) in a zero frame, flat: one column left, two right, one row above
    and below (width n_bins + 3), what :func:`read_cells` reads."""
    n_beams, n_bins = power.shape
    n_rows = n_beams + 2
    w = n_bins + 3
    pad = np.zeros((n_rows + 2) * w, np.float32)
    for a in range(n_rows):
        src = power[order[(a - 1) % n_beams]]
        for b in range(n_bins):
            pad[(a + 1) * w + b + 1] = src[b]
    return pad


@numba.njit(cache=True, nogil=True, error_model="numpy")
def read_cells(pad, n_beams, n_bins, spans, j0, j1, k0, r_read, r, row, offset_m, per_bin, r_min,
               grid):  # pragma: no cover - compiled
    """grid[j, k] for the packed disk cells of grid rows j0 to j1 - 1 (:func:`polar_cells`'
    order, row j0's first cell at packed index k0): the polar image of ``n_beams`` beams and
    ``n_bins`` bins (:func:`pad_polar`'s ``pad``) read at bin (r_read - offset) per_bin and
    fractional row ``row`` as ``cv2.remap(..., INTER_LINEAR, BORDER_CONSTANT 0)`` reads it, bit
    for bit (fused multiply-adds); 0 where the cell was nearer than r_min to its beam and off
    the disk (every cell of rows j0 to j1 - 1 is written; other rows are not touched)."""
    n_rows = n_beams + 2
    w = n_bins + 3
    zeros_at = n_bins + 1  # four zeros: what a cell reads when its four neighbours are all outside
    zero = np.float32(0.0)
    m = grid.shape[1]
    bfx, bfy, boff = np.empty(m, np.float32), np.empty(m, np.float32), np.empty(m, np.uint64)
    wu, one = np.uint64(w), np.uint64(1)  # unsigned offsets: no negative-index wrap in the gathers
    k = k0
    for j in range(j0, j1):
        lo = spans[j, 0]
        n = spans[j, 1] - lo
        rr, r0, ry = r_read[k:k + n], r[k:k + n], row[k:k + n]
        for t in range(n):
            sx = (rr[t] - offset_m) * per_bin
            sy = ry[t]
            fx, fy = np.floor(sx), np.floor(sy)
            ix, iy = np.int64(fx), np.int64(fy)
            bfx[t] = sx - fx
            bfy[t] = sy - fy
            inside = (ix >= -1) & (ix < n_bins) & (iy >= -1) & (iy < n_rows) & (r0[t] >= r_min)
            boff[t] = np.uint64((iy + 1) * w + ix + 1) if inside else np.uint64(zeros_at)
        row_j = grid[j]
        row_j[:lo] = zero  # off the disk
        row_j[lo + n:] = zero
        g = row_j[lo:lo + n]
        for t in range(n):
            o = boff[t]
            fx = bfx[t]
            p00, p01 = pad[o], pad[o + one]
            p10, p11 = pad[o + wu], pad[o + wu + one]
            v0 = _fma(fx, p01 - p00, p00)
            v1 = _fma(fx, p11 - p10, p10)
            g[t] = _fma(bfy[t], v1 - v0, v0)
        k += n


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
