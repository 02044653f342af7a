"""The odometry's compiled loops (numba, ``cache=True``; imported at their first call, never with
the plugin): the echoes' row medians and local maxima, their association, the search's
coincidence count and the map's binning. Each gives the same
bits as the numpy formulation it replaces (tests/slam/test_distortion_jit.py compares them)."""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["coincidences", "local_maxima", "map_cells", "mutual_nearest", "row_medians", "warm_up"]

_OFF = 1 << 20  # cell indices offset so that the keys' fields stay positive
_MIX = -7046029254386353131  # 0x9E3779B97F4A7C15 as an int64 (Fibonacci hashing)


@numba.njit(cache=True, nogil=True, inline="always")
def _key(x0, y0, x1, y1, ramp, v, inv):  # pragma: no cover - compiled
    ix = np.int64(math.floor((x0 + v * x1) * inv)) + _OFF
    iy = np.int64(math.floor((y0 + v * y1) * inv)) + _OFF
    return ((ramp << 21 | ix) << 21) | iy


@numba.njit(cache=True, nogil=True)
def coincidences(xa0, ya0, xa1, ya1, ra, xb0, yb0, xb1, yb1, rb, vs, inv, out):  # pragma: no cover - compiled
    """out[k, i] = how many echoes of ``a`` fall in a cell holding an echo of the same ramp of ``b``
    when both are placed for speed vs[k] and yaw rate i: an echo's point is (x0 + v x1, y0 + v y1)
    (rows i of the (n_w, n) terms), its cell floor(point * inv), ``ra``/``rb`` its ramp (1 rising,
    0 falling). ``b``'s cells go in an open-addressing hash table per candidate (a stamp per slot
    instead of clearing it), ``a``'s are looked up: O(n) per candidate."""
    nw, na = xa0.shape
    nb = xb0.shape[1]
    bits = 4
    while (1 << bits) < 2 * nb:
        bits += 1
    mask = (1 << bits) - 1
    shift = 64 - bits
    table = np.zeros(mask + 1, np.int64)
    stamp = np.full(mask + 1, -1, np.int64)
    cand = 0
    for i in range(nw):
        for k in range(vs.shape[0]):
            v = vs[k]
            for j in range(nb):
                key = _key(xb0[i, j], yb0[i, j], xb1[i, j], yb1[i, j], rb[j], v, inv)
                h = ((key * _MIX) >> shift) & mask
                while stamp[h] == cand and table[h] != key:
                    h = (h + 1) & mask
                stamp[h] = cand
                table[h] = key
            c = 0
            for j in range(na):
                key = _key(xa0[i, j], ya0[i, j], xa1[i, j], ya1[i, j], ra[j], v, inv)
                h = ((key * _MIX) >> shift) & mask
                while stamp[h] == cand:
                    if table[h] == key:
                        c += 1
                        break
                    h = (h + 1) & mask
            out[k, i] = c
            cand += 1


@numba.njit(cache=True, nogil=True, inline="always")
def _select(buf, n, k):  # pragma: no cover - compiled
    """Hoare selection in buf[:n]: afterwards buf[k] is the k-th smallest and buf[:k] <= buf[k]."""
    lo, hi = 0, n - 1
    while lo < hi:
        pivot = buf[(lo + hi) // 2]
        i, j = lo, hi
        while i <= j:
            while buf[i] < pivot:
                i += 1
            while buf[j] > pivot:
                j -= 1
            if i <= j:
                buf[i], buf[j] = buf[j], buf[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            break
    return buf[k]


@numba.njit(cache=True, nogil=True, inline="always")
def _order_key(u):  # pragma: no cover - compiled
    """A float32's bits (uint32) as a key (int64, 32 bits) that sorts as the values do: the sign bit
    flipped, and the other bits too for a negative value (without a branch)."""
    x = np.int64(u)
    return x ^ ((-(x >> 31) & 0x7FFFFFFF) | 0x80000000)


@numba.njit(cache=True, nogil=True)
def row_medians(p, out):  # pragma: no cover - compiled
    """out[b] = np.median(p[b]) of a float32 (rows, n) array, bit for bit: the middle element, or for
    an even n the half sum of the two middle ones in float32, as numpy computes it; NaN where the
    row holds a NaN. The middle element is found by radix selection on the values' order keys:
    counted by their top 11 bits (sign, exponent, two bits of mantissa), then, if the bin holding
    the middle holds many, by the next 11, then a quickselect among the values left; the one
    below it (even n) is the largest of those selected below it, else the row's largest smaller
    value. RADIATE's dB
    beams 3.2 -> 1.9 ms a turn, simulated ones (360 x 288) 1.4 -> 1.1 ms."""
    n = p.shape[1]
    bits = p.view(np.uint32)
    buf = np.empty(n, p.dtype)
    idx = np.empty(n, np.int64)
    counts = np.zeros(2048, np.int32)  # zero again after each use, over the bins used
    half = np.float32(0.5)
    k = n // 2
    for b in range(p.shape[0]):
        nan = n == 0
        lo, hi = np.int64(2047), np.int64(0)
        for j in range(n):
            if p[b, j] != p[b, j]:
                nan = True
            e = _order_key(bits[b, j]) >> 21
            counts[e] += 1
            lo, hi = min(lo, e), max(hi, e)
        if nan:
            counts[lo:hi + 1] = 0
            out[b] = np.float32(np.nan)
            continue
        rank, e1 = np.int64(k), lo  # rank of the middle among the values of bin e1
        while counts[e1] <= rank:
            rank -= counts[e1]
            e1 += 1
        size = counts[e1]
        counts[lo:hi + 1] = 0
        c = 0
        if size <= 128:  # few values in that bin: selected among directly
            for j in range(n):
                if (_order_key(bits[b, j]) >> 21) == e1:
                    buf[c] = p[b, j]
                    c += 1
        else:  # by the next 11 bits first
            m = 0
            lo, hi = np.int64(2047), np.int64(0)
            for j in range(n):
                key = _order_key(bits[b, j])
                if (key >> 21) == e1:
                    e = (key >> 10) & 2047
                    counts[e] += 1
                    lo, hi = min(lo, e), max(hi, e)
                    idx[m] = j
                    m += 1
            e2 = lo
            while counts[e2] <= rank:
                rank -= counts[e2]
                e2 += 1
            counts[lo:hi + 1] = 0
            for i in range(m):
                if ((_order_key(bits[b, idx[i]]) >> 10) & 2047) == e2:
                    buf[c] = p[b, idx[i]]
                    c += 1
        upper = _select(buf, c, rank)
        if n % 2:
            out[b] = upper
            continue
        if rank > 0:  # the largest of the values selected below it
            lower = buf[0]
            for i in range(1, rank):
                lower = max(lower, buf[i])
        else:  # the largest value of the lower bins: the largest smaller value of the row
            lower = np.float32(-np.inf)
            for j in range(n):
                x = p[b, j]
                lower = max(lower, x if x < upper else lower)
        out[b] = (lower + upper) * half


@numba.njit(cache=True, nogil=True)
def map_cells(px, py, cos_a, sin_a, rng, rel_db, cols, cell_m):  # pragma: no cover - compiled
    """Beams placed in map cells: beam b's bin cols[k] lands at (px[b] + rng[k] cos_a[b], py[b] +
    rng[k] sin_a[b]), cell floor(x / cell_m + 0.5); returns the window's first cell (ix0, iy0) and
    per cell (ny, nx) the sum of max(rel_db, 0) (float64, added in beam then bin order) and the
    count: what np.floor, np.bincount over the raveled (beams, bins) arrays give, in one pass
    without the (beams, bins) temporaries."""
    nb, nk = px.shape[0], rng.shape[0]
    ix = np.empty((nb, nk), np.int64)
    iy = np.empty((nb, nk), np.int64)
    ix0 = iy0 = np.int64(1) << 62
    ix1 = iy1 = -(np.int64(1) << 62)
    for b in range(nb):
        for k in range(nk):
            i = np.int64(math.floor((px[b] + rng[k] * cos_a[b]) / cell_m + 0.5))
            j = np.int64(math.floor((py[b] + rng[k] * sin_a[b]) / cell_m + 0.5))
            ix[b, k], iy[b, k] = i, j
            ix0, ix1, iy0, iy1 = min(ix0, i), max(ix1, i), min(iy0, j), max(iy1, j)
    ny, nx = iy1 - iy0 + 1, ix1 - ix0 + 1
    total = np.zeros((ny, nx))
    count = np.zeros((ny, nx), np.int64)
    for b in range(nb):
        for k in range(nk):
            v = rel_db[b, cols[k]]
            if v < 0:  # np.maximum(rel_db, 0): NaN kept
                v = np.float32(0.0)
            total[iy[b, k] - iy0, ix[b, k] - ix0] += v
            count[iy[b, k] - iy0, ix[b, k] - ix0] += 1
    return ix0, iy0, total, count


@numba.njit(cache=True, nogil=True)
def local_maxima(rel, n_rows, n_cols, k0, k1, threshold):  # pragma: no cover - compiled
    """(rows, columns) in row-major order of the cells of columns k0 <= k < k1 above ``threshold``
    (of rel's dtype) that are the maximum of their n_rows x n_cols window: what
    ``np.nonzero((rel == maximum_filter(rel, (n_rows, n_cols), mode=("wrap", "nearest"))) &
    (rel > threshold))`` gives there (window offsets -(n // 2) .. n - 1 - n // 2, rows wrapping
    around the turn, columns repeating their edge). Only the cells above the threshold look at their
    window (2 to 20 in a hundred), their 4 neighbours first, and stop at the first larger value."""
    n, m = rel.shape
    top, left = n_rows // 2, n_cols // 2
    rows = np.empty(n * max(k1 - k0, 0), np.int64)
    cols = np.empty_like(rows)
    found = 0
    near = n_rows >= 3 and n_cols >= 3 and k0 >= 1 and k1 <= m - 1  # the window holds the 4 neighbours
    for b in range(n):
        up, down = (b - 1) % n, (b + 1) % n
        for k in range(k0, k1):
            v = rel[b, k]
            if not v > threshold:
                continue
            if near and not (rel[b, k - 1] <= v and rel[b, k + 1] <= v and rel[up, k] <= v and rel[down, k] <= v):
                continue  # most cells above the threshold are not the largest of their 4 neighbours
            peak = True
            for db in range(-top, n_rows - top):
                r = (b + db) % n
                for dk in range(-left, n_cols - left):
                    if not rel[r, min(max(k + dk, 0), m - 1)] <= v:
                        peak = False
                        break
                if not peak:
                    break
            if peak:
                rows[found], cols[found] = b, k
                found += 1
    return rows[:found], cols[:found]


@numba.njit(cache=True, nogil=True, inline="always")
def _nearest(x, y, q, order, xs, ramp, same, reach):  # pragma: no cover - compiled
    """Index of the point of q (n, 2) with ramp ``same`` nearest (x, y), the lowest of equals, and its
    squared distance ((dx^2 + dy^2), as scipy's cKDTree sums it), among those within ``reach`` in
    x (``order`` sorts q by x, ``xs`` its sorted x): -1 and inf when there is none."""
    best, d2 = -1, np.inf
    k = np.searchsorted(xs, x - reach)
    while k < xs.shape[0] and xs[k] <= x + reach:
        j = order[k]
        k += 1
        if ramp[j] == same:
            dx, dy = x - q[j, 0], y - q[j, 1]
            d = dx * dx + dy * dy
            if d < d2 or (d == d2 and j < best):
                best, d2 = j, d
    return best, d2


@numba.njit(cache=True, nogil=True)
def mutual_nearest(pa, pb, ramp_a, ramp_b, gate):  # pragma: no cover - compiled
    """Pairs (i, j): pb[j] is pa[i]'s nearest point of the same ramp, nearer than ``gate``, and pa[i]
    is pb[j]'s nearest; rising ramp first, each by increasing i: what two cKDTree queries per ramp
    give (its distances, its strict bound). Each side sorted by x instead of a tree: only the
    points within the gate in x are looked at (any nearer point is among them)."""
    ia = np.empty(pa.shape[0], np.int64)
    ib = np.empty_like(ia)
    g2 = gate ** 2
    reach = gate * (1.0 + 1e-9) + 1e-9  # the strip in x, a little wider than the gate
    order_a, order_b = np.argsort(pa[:, 0]), np.argsort(pb[:, 0])
    xs_a, xs_b = pa[order_a, 0], pb[order_b, 0]
    found = 0
    for sign in (1.0, -1.0):
        for i in range(pa.shape[0]):
            if ramp_a[i] != sign:
                continue
            j, d2 = _nearest(pa[i, 0], pa[i, 1], pb, order_b, xs_b, ramp_b, sign, reach)
            if j < 0 or not d2 < g2:
                continue
            back, _ = _nearest(pb[j, 0], pb[j, 1], pa, order_a, xs_a, ramp_a, sign, reach)
            if back == i:
                ia[found], ib[found] = i, j
                found += 1
    return ia[:found], ib[:found]


def warm_up() -> None:
    """Each loop called once on tiny inputs: numba's import and its cache loaded (compiled on the
    first use on a machine), so that the first turns do not pay it."""
    t = np.zeros((1, 1))
    r = np.zeros(1, np.int64)
    coincidences(t, t, t, t, r, t, t, t, t, r, np.zeros(1), 1.0, np.zeros((1, 1), np.int64))
    row_medians(np.zeros((1, 2), np.float32), np.zeros(1, np.float32))
    local_maxima(np.ones((3, 3), np.float32), 3, 3, 0, 3, np.float32(0.0))
    mutual_nearest(np.zeros((1, 2)), np.zeros((1, 2)), np.ones(1), np.ones(1), 1.0)
    one = np.ones(1)
    map_cells(one, one, one, one, one, np.ones((1, 1), np.float32), np.zeros(1, np.int64), 0.5)
    from .fit import fit_pairs

    e = np.array([[0.0], [0.0], [0.0], [1.0], [0.0], [10.0]])
    fit_pairs(np.array([1.0, 0.0]), e, e, 0.1, np.ones(1), 0.0, 1.0, 2.0, np.ones(2))
