"""R-SLAM's compiled loops (numba, ``cache=True``, nogil; imported by ``RSlam.start()`` or at the
first map update or read, never with the plugin), each one pass: the merge of a turn into a map
tile (eq. 6), the read of a tile's weighted mean, :func:`~impala_slam.rslam.matching.contrast`,
the first half of the correlator's partial inverse DFT (:func:`rows_product`).
All but the last give the bits of the formulations they replace (alpha zeroed where the amplitude is NaN,
alpha A, a masked add and the normaliser's add; a masked division and the support; two
cv2.blur, a masked division, a difference and a product; tests/slam/test_rslam_threads.py
compares them)."""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["contrast_box", "db_tail", "merge_tile", "mean_tile", "rows_product"]


# one signature each, any-layout float32 images (views of tiles and windows are C-contiguous or not
# by chance): compiled or loaded from the cache once, when this module is imported (RSlam.start),
# never again at a turn
_IMG = numba.float32[:, :]
_CIMG = numba.float32[:, ::1]  # C-contiguous: the compiled loops vectorise (contrast_box: 2x faster than on _IMG)
# inputs only read may be read-only (a frozen message's image)
_RIMG = numba.types.Array(numba.float32, 2, "A", readonly=True)
_RCIMG = numba.types.Array(numba.float32, 2, "C", readonly=True)


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


@numba.njit(nogil=True, cache=True)
def _row_sums(v, sup, k, pm, pw, dm, dw):  # pragma: no cover - compiled
    """cv2.blur's row pass (OpenCV's RowSum<float, double>) of ``v * sup`` (float32 products)
    into ``dm`` and of ``sup`` into ``dw``: the row is copied, in float64, into the middle of
    ``pm`` / ``pw`` (k // 2 zeros each side, BORDER_CONSTANT); k = 3 or 5 summed directly,
    longer windows by OpenCV's running sum s += new - old."""
    w = v.shape[0]
    r = k // 2
    for x in range(w):
        pm[r + x] = np.float64(v[x] * sup[x])
        pw[r + x] = np.float64(sup[x])
    if k == 3 or k == 5:
        for i in range(w):
            sm = pm[i]
            sw = pw[i]
            for q in range(1, k):
                sm += pm[i + q]
                sw += pw[i + q]
            dm[i] = sm
            dw[i] = sw
        return
    sm = 0.0
    sw = 0.0
    for q in range(k):
        sm += pm[q]
        sw += pw[q]
    dm[0] = sm
    dw[0] = sw
    for i in range(w - 1):
        sm += pm[i + k] - pm[i]
        sw += pw[i + k] - pw[i]
        dm[i + 1] = sm
        dw[i + 1] = sw


@numba.njit([numba.void(_CIMG, _CIMG, numba.int64, _CIMG), numba.void(_RCIMG, _RCIMG, numba.int64, _CIMG),
             numba.void(_IMG, _IMG, numba.int64, _CIMG), numba.void(_RIMG, _RIMG, numba.int64, _CIMG)],
            cache=True, nogil=True, error_model="numpy")
def contrast_box(img, support, k, out):  # pragma: no cover - compiled
    """:func:`~impala_slam.rslam.matching.contrast` in one pass over the rows: the two k x k box
    means of ``img * support`` and of ``support`` (cv2.blur with BORDER_CONSTANT: its float64
    row sums, then its running column sums SUM + new row, scaled, SUM - old row), then
    ``out = (img - mean / weight) * support``, the division only where weight > 1e-3 (float32).
    The same bits as cv2.blur twice and the numpy tail (tests/slam/test_rslam_threads.py), with
    k rows of sums in cache instead of four image-sized passes through memory."""
    h, w = img.shape
    r = k // 2
    scale = 1.0 / (k * k)
    eps = np.float32(1e-3)
    ring_m = np.zeros((k, w))  # the row sums of padded rows p .. p + k - 1, row p in slot p % k
    ring_w = np.zeros((k, w))
    pm = np.zeros(w + 2 * r)  # one padded row, float64
    pw = np.zeros(w + 2 * r)
    sum_m = np.zeros(w)
    sum_w = np.zeros(w)
    zero_row = np.zeros(w, np.float32)
    for p in range(k - 1):  # padded row p is image row p - r (zeros outside)
        y = p - r
        if 0 <= y < h:
            _row_sums(img[y], support[y], k, pm, pw, ring_m[p % k], ring_w[p % k])
        else:
            _row_sums(zero_row, zero_row, k, pm, pw, ring_m[p % k], ring_w[p % k])
        for i in range(w):
            sum_m[i] += ring_m[p % k, i]
            sum_w[i] += ring_w[p % k, i]
    for yo in range(h):
        p = yo + k - 1
        y = yo + r
        if y < h:
            _row_sums(img[y], support[y], k, pm, pw, ring_m[p % k], ring_w[p % k])
        else:
            _row_sums(zero_row, zero_row, k, pm, pw, ring_m[p % k], ring_w[p % k])
        sp_m, sp_w = ring_m[p % k], ring_w[p % k]
        sm_m, sm_w = ring_m[yo % k], ring_w[yo % k]
        g_row, s_row, o_row = img[yo], support[yo], out[yo]
        for i in range(w):
            s0 = sum_m[i] + sp_m[i]
            s1 = sum_w[i] + sp_w[i]
            sum_m[i] = s0 - sm_m[i]
            sum_w[i] = s1 - sm_w[i]
            m = np.float32(s0 * scale)
            wt = np.float32(s1 * scale)
            q = m / wt  # computed everywhere (vectorised), kept where weight > 1e-3
            o_row[i] = (g_row[i] - (q if wt > eps else m)) * s_row[i]


_F32 = numba.float32


@numba.njit([numba.void(_CIMG, _CIMG, _F32, _F32), numba.void(_CIMG, _RCIMG, _F32, _F32),
             numba.void(_IMG, _IMG, _F32, _F32), numba.void(_IMG, _RIMG, _F32, _F32)], cache=True, nogil=True)
def db_tail(a, p, log_floor, gain):  # pragma: no cover - compiled
    """In place in ``a`` (ln max(p, floor)): ``(a - log_floor) * gain`` where p > 0, 0 elsewhere
    (NaN included), float32: the subtraction, product, comparison and masked copy of
    :meth:`~impala_slam.rslam.core.RSlamCore.amplitude` in one pass."""
    zero = np.float32(0.0)
    for i in range(a.shape[0]):
        a_row, p_row = a[i], p[i]
        for j in range(a.shape[1]):
            a_row[j] = (a_row[j] - log_floor) * gain if p_row[j] > zero else zero




@numba.njit(numba.void(_CIMG, _CIMG, _CIMG, _CIMG), cache=True, nogil=True)
def rows_product(rows, spec_a, spec_b, out):  # pragma: no cover - compiled
    """``out = rows @ (spec_a conj(spec_b))`` over the columns 1 .. n - 2 of two CCS-packed spectra
    (:func:`cv2.dft`'s layout: there, (re, im) pairs of one frequency per row; the product as
    :func:`cv2.mulSpectrums` with ``conjB``, formed four rows at a time and never stored whole);
    the columns 0 and n - 1 of ``out`` are left 0. float32, each row read once, in a fixed order:
    numpy's BLAS product (0.33 ms against 0.51 ms for 18 x 640 x 640) starts threads of its own,
    spinning against the pool's (R-SLAM's CPU per turn 54 -> 70 ms on Beynes unless
    OMP_NUM_THREADS=1)."""
    out[:] = 0.0
    n_u, n_v = spec_a.shape
    buf = np.zeros((4, n_v), np.float32)
    for u0 in range(0, n_u, 4):
        m = min(4, n_u - u0)
        for r in range(m):
            a, b, p = spec_a[u0 + r], spec_b[u0 + r], buf[r]
            for v in range(1, n_v - 1, 2):
                p[v] = a[v] * b[v] + a[v + 1] * b[v + 1]
                p[v + 1] = a[v + 1] * b[v] - a[v] * b[v + 1]
        if m == 4:
            s0, s1, s2, s3 = buf[0], buf[1], buf[2], buf[3]
            for i in range(rows.shape[0]):
                w0, w1, w2, w3 = rows[i, u0], rows[i, u0 + 1], rows[i, u0 + 2], rows[i, u0 + 3]
                o = out[i]
                for v in range(n_v):
                    o[v] += (w0 * s0[v] + w1 * s1[v]) + (w2 * s2[v] + w3 * s3[v])
        else:
            for r in range(m):
                for i in range(rows.shape[0]):
                    w = rows[i, u0 + r]
                    for v in range(n_v):
                        out[i, v] += w * buf[r, v]
