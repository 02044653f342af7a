"""Compiled loops of the simulator: NUFFT spreading (:class:`.spectra.Synthesizer`) and the
beam x scatterer pairs of static echoes (:func:`.spectra.echoes`).

Numba (``cache=True``: compiled once per machine into ``__pycache__``, about 2 s, then
loaded in milliseconds); this module is imported by the first :meth:`Synthesizer.signal`
call, never by the plugin's import. The loops do what the numpy expressions they replace
did, in the same order and the same float types, so the spectra are bit for bit those of
the numpy formulation: the kernel's exponential and the phasors' cosines stay numpy's
(its SIMD ``exp``/``cos``/``sin`` round differently from libm); what is compiled is the
arithmetic around them (one pass instead of ten over (echoes x 6) arrays) and the
accumulation onto the grid, whose float64 sums run in the order ``np.bincount`` used.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["grid_positions", "kernel_arguments", "spread", "wrap_phase32", "static_pairs", "segments_clear",
           "discs_transmission", "block_spans", "block_candidates", "table_gain2"]


@numba.njit(cache=True, nogil=True)
def _mod(a: float, b: float) -> float:
    """numpy's float remainder (npy_divmod): fmod, moved into [0, b) for b > 0."""
    r = a if -b < a < b else np.fmod(a, b)  # fmod is exact (numba has no math.fmod): a itself when |a| < b
    if r != 0.0:
        if (b < 0.0) != (r < 0.0):
            r += b
    else:
        r = math.copysign(0.0, b)
    return r


@numba.njit(cache=True, nogil=True)
def grid_positions(f_hz, scale, m_grid):
    """``(f_hz * scale) % m_grid``: each echo's position on the spreading grid, in [0, M)."""
    out = np.empty(f_hz.shape[0])
    for i in range(f_hz.shape[0]):
        out[i] = _mod(f_hz[i] * scale, m_grid)
    return out


@numba.njit(cache=True, nogil=True)
def wrap_phase32(phase_rad):
    """``(phase % 2 pi).astype(float32)``."""
    out = np.empty(phase_rad.shape[0], np.float32)
    for i in range(phase_rad.shape[0]):
        out[i] = np.float32(_mod_2pi(phase_rad[i]))
    return out


@numba.njit(cache=True, nogil=True)
def kernel_arguments(x, beam, row, offsets, u_scale, beta):
    """The exponent beta (sqrt(1 - u^2) - 1) of the ES kernel at the grid points around each
    echo (float32, (n, width)) and the flat index of each echo's first grid point."""
    n, width = x.shape[0], offsets.shape[0]
    arg = np.empty((n, width), np.float32)
    base = np.empty(n, np.intp)
    one = np.float32(1.0)
    zero = np.float32(0.0)
    for i in range(n):
        i0 = math.floor(x[i])
        frac = np.float32(x[i] - i0)
        base[i] = np.intp(beam[i]) * row + np.intp(i0)
        for k in range(width):
            u = (offsets[k] - frac) * u_scale
            v = one - u * u
            if not v >= zero:  # np.maximum(v, 0)
                v = zero
            arg[i, k] = beta * (np.sqrt(v) - one)
    return arg, base


@numba.njit(cache=True, nogil=True)
def spread(base, ker, a_re, a_im, size):
    """Grid sums b[base_i + k] += ker[i, k] a_i (float32 products, float64 sums in echo order)."""
    b_re = np.zeros(size)
    b_im = np.zeros(size)
    for i in range(base.shape[0]):
        ar, ai, b = a_re[i], a_im[i], base[i]
        for k in range(ker.shape[1]):
            w = ker[i, k]
            b_re[b + k] += np.float64(w * ar)
            b_im[b + k] += np.float64(w * ai)
    return b_re, b_im


@numba.njit(cache=True, nogil=True)
def static_pairs(rx, ry, c, s, sx, sy, tan_cut, r2_max, visible):
    """The (beam, scatterer) pairs where a static scatterer lies in front of the antenna,
    within ``tan_cut`` of its axis, ``r2_max`` of squared range and ``visible``, in
    ``np.nonzero`` order (beam-major), with their offsets dx, dy, along, across and r2."""
    nb, ns = rx.shape[0], sx.shape[0]
    bi = np.empty(nb * ns, np.intp)
    si = np.empty(nb * ns, np.intp)
    out = np.empty((5, nb * ns))
    n = 0
    for b in range(nb):
        for j in range(ns):
            if not visible[j]:
                continue
            dx = sx[j] - rx[b]
            dy = sy[j] - ry[b]
            along = dx * c[b] + dy * s[b]
            across = dy * c[b] - dx * s[b]
            r2 = dx * dx + dy * dy
            if along > 0.0 and abs(across) <= tan_cut[j] * along and r2 <= r2_max:
                bi[n], si[n] = b, j
                out[0, n], out[1, n], out[2, n], out[3, n], out[4, n] = dx, dy, along, across, r2
                n += 1
    return bi[:n], si[:n], out[:, :n]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _segment_clear(px, py, qx, qy, seg, eps_m):
    """True where the ray p -> q crosses none of ``seg`` (a, b) (one ray of :func:`segments_clear`)."""
    rx, ry = qx - px, qy - py
    t_max = 1.0 - eps_m / max(np.hypot(rx, ry), eps_m)
    for k in range(seg.shape[0]):
        sx, sy = seg[k, 2] - seg[k, 0], seg[k, 3] - seg[k, 1]
        apx, apy = seg[k, 0] - px, seg[k, 1] - py
        den = rx * sy - ry * sx
        t = (apx * sy - apy * sx) / den  # along the ray: 0 radar, 1 scatterer
        u = (apx * ry - apy * rx) / den  # along the segment
        if t > 0.0 and t < t_max and u >= 0.0 and u <= 1.0:
            return False
    return True


@numba.njit(cache=True, nogil=True, error_model="numpy")
def segments_clear(px, py, qx, qy, seg, eps_m):
    """True where the ray p -> q crosses none of ``seg`` (a, b) (:meth:`.world.World.visible`;
    the same arithmetic, stopping at the first crossing)."""
    n = px.shape[0]
    out = np.ones(n, np.bool_)
    for i in range(n):
        out[i] = _segment_clear(px[i], py[i], qx[i], qy[i], seg, eps_m)
    return out


@numba.njit(cache=True, nogil=True)
def _disc_product(px, py, qx, qy, qz, radar_z_m, discs, k0, k1, eps_m):
    """Product of the transmissions of the discs ``k0:k1`` the ray p -> q crosses (one ray of
    :func:`discs_transmission`)."""
    rx, ry = qx - px, qy - py
    l2 = max(rx * rx + ry * ry, 1e-12)
    t_max = 1.0 - eps_m / np.sqrt(l2)
    p = 1.0
    for k in range(k0, k1):
        ax, ay = discs[k, 0] - px, discs[k, 1] - py
        t = (ax * rx + ay * ry) / l2
        if not (t > 0.0 and t < t_max):
            continue
        ex, ey = ax - t * rx, ay - t * ry
        z_ray = radar_z_m + t * (qz - radar_z_m)
        if ex * ex + ey * ey < discs[k, 2] * discs[k, 2] and z_ray >= discs[k, 3] and z_ray <= discs[k, 4]:
            p *= discs[k, 5]
    return p


@numba.njit(cache=True, nogil=True)
def discs_transmission(px, py, qx, qy, qz, radar_z_m, discs, eps_m):
    """Product of the transmissions of the discs the ray p -> q crosses
    (:func:`.world.disc_transmission`; the same arithmetic, products in disc order)."""
    n = px.shape[0]
    out = np.ones(n)
    for i in range(n):
        out[i] = _disc_product(px[i], py[i], qx[i], qy[i], qz[i], radar_z_m, discs, 0, discs.shape[0], eps_m)
    return out


@numba.njit(cache=True, nogil=True)
def _wrap(a: float) -> float:
    """:func:`impala_flow.msgs.wrap_angle` of a float: (a + pi) % 2 pi - pi."""
    return _mod(a + math.pi, 2.0 * math.pi) - math.pi


@numba.njit(cache=True, nogil=True)
def block_spans(beam_dir, block):
    """Per block of ``block`` beams: the middle direction and the half-span of its beams'
    directions once unwrapped (``np.unwrap`` of the block, then its ends)."""
    n = beam_dir.shape[0]
    nb = (n + block - 1) // block
    mid, half = np.empty(nb), np.empty(nb)
    for b in range(nb):
        lo, hi = b * block, min(n, (b + 1) * block)
        c = 0.0  # np.unwrap: cumulative correction of the jumps beyond pi
        for k in range(lo + 1, hi):
            dd = beam_dir[k] - beam_dir[k - 1]
            ddmod = _mod(dd + math.pi, 2.0 * math.pi) - math.pi
            if ddmod == -math.pi and dd > 0.0:
                ddmod = math.pi
            pc = ddmod - dd
            if abs(dd) < math.pi:
                pc = 0.0
            c = pc if k == lo + 1 else c + pc
        first, last = beam_dir[lo], beam_dir[hi - 1] + c if hi - 1 > lo else beam_dir[lo]
        mid[b], half[b] = _wrap(0.5 * (first + last)), 0.5 * abs(last - first)
    return mid, half


@numba.njit(cache=True, nogil=True)
def block_candidates(far, far_bearing, near, bearing, slack, mid, half, far_slack):
    """Scatterers whose bearing from the turn centre may fall in a block's beams: the far ones
    (sorted by bearing) within ``half + far_slack`` of ``mid`` by binary search, then the near
    ones, each kept if |wrap(bearing - mid)| <= half + its slack."""
    out = np.empty(far.shape[0] + near.shape[0], np.intp)
    n = 0
    w = half + far_slack
    lo, hi = mid - w, mid + w
    ranges = np.empty((3, 2))
    nr = 1
    if w >= math.pi:
        ranges[0, 0], ranges[0, 1] = -np.inf, np.inf
    else:
        ranges[0, 0], ranges[0, 1] = max(lo, -math.pi), min(hi, math.pi)
        if lo < -math.pi:
            ranges[nr, 0], ranges[nr, 1] = lo + 2.0 * math.pi, math.pi
            nr += 1
        if hi > math.pi:
            ranges[nr, 0], ranges[nr, 1] = -math.pi, hi - 2.0 * math.pi
            nr += 1
    for r in range(nr):
        if w >= math.pi:
            i0, i1 = 0, far.shape[0]
        else:
            i0 = np.searchsorted(far_bearing, ranges[r, 0], side="left")
            i1 = np.searchsorted(far_bearing, ranges[r, 1], side="right")
        for i in range(i0, i1):
            j = far[i]
            if abs(_wrap(bearing[j] - mid)) <= half + slack[j]:
                out[n] = j
                n += 1
    for i in range(near.shape[0]):
        j = near[i]
        if abs(_wrap(bearing[j] - mid)) <= half + slack[j]:
            out[n] = j
            n += 1
    return out[:n]


@numba.njit(cache=True, nogil=True)
def table_gain2(d_azimuth_rad, u_per_rad, inv_step, g2):
    """:meth:`.antenna.AzimuthPattern.gain2` of the tabulated pattern: u = |d| u_per_rad, then
    the linear interpolation in ``g2`` (step 1 / ``inv_step``), the same float64 operations."""
    n, top = d_azimuth_rad.shape[0], g2.shape[0] - 1.0
    k_max = g2.shape[0] - 2
    out = np.empty(n)
    for i in range(n):
        pos = abs(d_azimuth_rad[i]) * u_per_rad * inv_step
        if not pos <= top:  # np.minimum
            pos = top
        k = min(np.intp(pos), k_max)
        frac = pos - k
        out[i] = g2[k] * (1.0 - frac) + g2[k + 1] * frac
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def block_pairs(b_first, b_last, block, mids, halves, far, far_bearing, near, bearing, slack, far_slack,
                rx, ry, cos_b, sin_b, sx, sy, sz, tan_cut, r2_max, ghost, behind, use_behind, segs,
                occ, occ_lo, radar_z_m, eps_m, cap):
    """The (beam, scatterer) pairs of the blocks ``b_first .. b_last - 1`` of ``block`` beams (the
    loop of :meth:`.core.RadarSimulator._static` in one pass): per block its candidates
    (:func:`block_candidates`), their walls (:func:`segments_clear`, ``ghost`` ones see through)
    and discs (``occ[occ_lo[i]:occ_lo[i + 1]]`` for the i-th block, on the ``behind`` ones when
    ``use_behind``; :func:`discs_transmission`) from the block's middle pose, then the pairs of
    :func:`static_pairs` among the visible ones. Returns the pairs' beam, scatterer, and
    (6, n) dx, dy, along, across, r2 and the two-way transmission; ``cap`` is the first guess
    of their number (the buffers grow if it is short)."""
    n_beams = rx.shape[0]
    cap = max(cap, 1024)
    beam = np.empty(cap, np.intp)
    jj = np.empty(cap, np.intp)
    d = np.empty((6, cap))
    n = 0
    ns = sx.shape[0]
    gq, gx, gy, gt, gv = np.empty(ns, np.intp), np.empty(ns), np.empty(ns), np.empty(ns), np.empty(ns)
    for b in range(b_first, b_last):
        b0, b1 = b * block, min(n_beams, (b + 1) * block)
        j = block_candidates(far, far_bearing, near, bearing, slack, mids[b], halves[b], far_slack)
        nj = j.shape[0]
        if nj == 0:
            continue
        pm = (b0 + b1 - 1) // 2
        px, py = rx[pm], ry[pm]
        k0, k1 = occ_lo[b - b_first], occ_lo[b - b_first + 1]
        vis = np.empty(nj)
        for i in range(nj):
            q = j[i]
            v = 1.0
            if segs.shape[0] > 0 and not ghost[q] and not _segment_clear(px, py, sx[q], sy[q], segs, eps_m):
                v = 0.0
            if k1 > k0 and (not use_behind or behind[q]):
                v = _disc_product(px, py, sx[q], sy[q], sz[q], radar_z_m, occ, k0, k1, eps_m) * v
            vis[i] = v
        if n + (b1 - b0) * nj > cap:
            while n + (b1 - b0) * nj > cap:
                cap *= 2
            beam2, jj2, d2 = np.empty(cap, np.intp), np.empty(cap, np.intp), np.empty((6, cap))
            beam2[:n], jj2[:n], d2[:, :n] = beam[:n], jj[:n], d[:, :n]
            beam, jj, d = beam2, jj2, d2
        nv = 0  # the visible candidates, gathered
        for i in range(nj):
            if vis[i] > 0.0:
                q = j[i]
                gq[nv], gx[nv], gy[nv], gt[nv], gv[nv] = q, sx[q], sy[q], tan_cut[q], vis[i]
                nv += 1
        for bm in range(b0, b1):
            c, s, px_b, py_b = cos_b[bm], sin_b[bm], rx[bm], ry[bm]
            for i in range(nv):
                dx = gx[i] - px_b
                dy = gy[i] - py_b
                along = dx * c + dy * s
                across = dy * c - dx * s
                r2 = dx * dx + dy * dy
                if along > 0.0 and abs(across) <= gt[i] * along and r2 <= r2_max:
                    beam[n], jj[n] = bm, gq[i]
                    d[0, n], d[1, n], d[2, n], d[3, n], d[4, n], d[5, n] = dx, dy, along, across, r2, gv[i]
                    n += 1
    return beam[:n], jj[:n], d[:, :n]


@numba.njit(cache=True, nogil=True)
def pair_ranges(beam, jj, d, sz, height_m, rvx, rvy):
    """The arithmetic of :func:`.spectra.pair_echoes` before its transcendental functions, for
    static pairs (``d`` from :func:`block_pairs`): horizontal range, height difference, slant
    range and radial speed (the radar's velocity ``rvx, rvy`` per beam)."""
    n = beam.shape[0]
    r_h, dz, rng, radial = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for i in range(n):
        rh = np.sqrt(d[4, i])
        z = sz[jj[i]] - height_m
        r = np.sqrt(rh * rh + z * z)
        b = beam[i]
        r_h[i], dz[i], rng[i] = rh, z, r
        radial[i] = (d[0, i] * -rvx[b] + d[1, i] * -rvy[b]) / r
    return r_h, dz, rng, radial


@numba.njit(cache=True, nogil=True)
def elevation_exponent(el, width_rad, c):
    """``c * (el / width_rad) ** 2``: the exponent of the elevation pattern."""
    out = np.empty(el.shape[0])
    for i in range(el.shape[0]):
        q = el[i] / width_rad
        out[i] = c * (q * q)
    return out


@numba.njit(cache=True, nogil=True)
def pair_power(beam, jj, d, g_az, e_el, dz, rng, r4, radial, rcs, phase, area, grazing, sin_ref, k, g2_min,
               cull, p_min):
    """The rest of :func:`.spectra.pair_echoes` for static pairs: two-way gain, grazing law (when
    ``grazing``; sin psi / ``sin_ref``), transmission ``d[5]``, radar equation, then only
    the pairs whose gain reaches ``g2_min`` and, when ``cull``, whose power reaches ``p_min`` (the
    synthesizer's culling), in order: (beam, range, radial, power, phase)."""
    n = beam.shape[0]
    ob, orng, orad, opow, oph = np.empty(n, np.intp), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    m = 0
    for i in range(n):
        g2 = g_az[i] * e_el[i]
        q = jj[i]
        r = rcs[q]
        if grazing:
            r = r * ((abs(dz[i]) / rng[i]) / sin_ref if area[q] > 0.0 else 1.0)
        r = r * d[5, i]
        p = k * r * g2 / r4[i]
        if g2 >= g2_min and (not cull or p >= p_min):
            ob[m], orng[m], orad[m], opow[m], oph[m] = beam[i], rng[i], radial[i], p, phase[q]
            m += 1
    return ob[:m], orng[:m], orad[:m], opow[:m], oph[:m]


_TWO_PI = 2.0 * math.pi
_TWO_PI_HI = float(np.float32(_TWO_PI))  # 24 significant bits: q * hi is exact for q < 2 ** 29
_TWO_PI_LO = _TWO_PI - _TWO_PI_HI  # exact, 29 bits: q * lo is exact for q < 2 ** 24


@numba.njit(cache=True, nogil=True)
def _mod_2pi(a: float) -> float:
    """``_mod(a, 2 pi)``, with the truncated remainder computed exactly without ``fmod`` for
    |a| < 2 ** 24 turns: q = trunc(a / 2 pi) (corrected by one if the division rounded across an
    integer), then (|a| - q hi) - q lo, each step exact (the products fit 53 bits, the first
    difference by Sterbenz's lemma, the second because the remainder is representable)."""
    b = _TWO_PI
    if -b < a < b:
        r = a
    else:
        x = abs(a)
        q = np.floor(x / b)  # a float (math.floor would be an int64, overflowing)
        if not q < 16777216.0:
            r = np.fmod(a, b)
        else:
            r = (x - q * _TWO_PI_HI) - q * _TWO_PI_LO
            if r < 0.0:
                q -= 1.0
                r = (x - q * _TWO_PI_HI) - q * _TWO_PI_LO
            elif r >= b:
                q += 1.0
                r = (x - q * _TWO_PI_HI) - q * _TWO_PI_LO
            if a < 0.0:
                r = -r
    if r != 0.0:
        if r < 0.0:
            r += b
    else:
        r = 0.0
    return r


@numba.njit(cache=True, nogil=True)
def ramp_echoes(beam, range_m, radial, power, phase, mode, c_range, range_offset_m, c_doppler, c_half, k_phase,
                half_fs, scale, m_grid, row, offsets, u_scale, beta):
    """One ramp's echoes as :meth:`.spectra.Synthesizer.spectra` and ``signal`` prepare them, in
    one pass: beat frequency f (``mode`` 0 single ramp f_r + 2 f_d, 1 up f_r + f_d, 2 down
    f_r - f_d) and phase (range phase -+ the half-ramp motion), then for the echoes with
    |f| < fs/2 the exponents of the kernel at their grid points (:func:`kernel_arguments`),
    their first grid index, the phase mod 2 pi and the amplitude sqrt(2 P) in float32.
    Returns (f for every echo, arg, base, phase32, amp32)."""
    n, width = beam.shape[0], offsets.shape[0]
    f_all = np.empty(n)
    ph_all = np.empty(n)
    for i in range(n):
        f_r = c_range * (range_m[i] - range_offset_m)
        f_d = c_doppler * radial[i]
        if mode == 0:
            f = f_r + 2.0 * f_d
            ph = phase[i] + k_phase * range_m[i]
        elif mode == 1:
            f = f_r + f_d
            ph = phase[i] + k_phase * (range_m[i] - c_half * radial[i])
        else:
            f = f_r - f_d
            ph = phase[i] + k_phase * (range_m[i] + c_half * radial[i])
        f_all[i] = f
        ph_all[i] = ph
    keep = np.empty(n, np.intp)
    m = 0
    for i in range(n):
        if abs(f_all[i]) < half_fs:
            keep[m] = i
            m += 1
    frac = np.empty(m, np.float32)
    base = np.empty(m, np.intp)
    ph32 = np.empty(m, np.float32)
    amp32 = np.empty(m, np.float32)
    for t in range(m):
        i = keep[t]
        x = _mod(f_all[i] * scale, m_grid)
        i0 = math.floor(x)
        frac[t] = np.float32(x - i0)
        base[t] = np.intp(beam[i]) * row + np.intp(i0)
        amp32[t] = np.float32(np.sqrt(2.0 * power[i]))
    for t in range(m):
        ph32[t] = np.float32(_mod_2pi(ph_all[keep[t]]))
    arg = np.empty((m, width), np.float32)
    one = np.float32(1.0)
    zero = np.float32(0.0)
    for t in range(m):
        for k in range(width):
            u = (offsets[k] - frac[t]) * u_scale
            arg[t, k] = beta * (np.sqrt(max(one - u * u, zero)) - one)  # u is finite: max is np.maximum
    return f_all, arg, base, ph32, amp32


@numba.njit(cache=True, nogil=True)
def spread_fold(base, ker, amp32, cos32, sin32, n_beams, m_grid, o):
    """:func:`spread` with a_re, a_im = amp32 cos, amp32 sin (float32), onto one padded row per
    beam, then the complex grid b + 1j b_im (numpy's arithmetic) with the wrapped columns folded
    (padded column c is grid point (c - o) mod M), as :meth:`.spectra.Synthesizer.signal` does."""
    width = ker.shape[1]
    row = m_grid + width - 1
    g = np.zeros(2 * n_beams * row)  # re, im interleaved: the same sums, closer in memory
    for i in range(base.shape[0]):
        ar, ai, b = amp32[i] * cos32[i], amp32[i] * sin32[i], 2 * base[i]
        for k in range(width):
            w = ker[i, k]
            g[b + 2 * k] += np.float64(w * ar)
            g[b + 2 * k + 1] += np.float64(w * ai)
    out = np.empty((n_beams, m_grid), np.complex128)
    for r in range(n_beams):
        p0 = 2 * r * row
        for c in range(m_grid):
            q = p0 + 2 * (o + c)
            out[r, c] = _b(g[q], g[q + 1])
        for c in range(o):  # b[:, M - o:] += padded[:, :o]
            q = p0 + 2 * c
            out[r, m_grid - o + c] += _b(g[q], g[q + 1])
        for c in range(width - 1 - o):  # b[:, :width - 1 - o] += padded[:, o + M:]
            q = p0 + 2 * (o + m_grid + c)
            out[r, c] += _b(g[q], g[q + 1])
    return out


@numba.njit(cache=True, nogil=True)
def _b(re, im):
    """numpy's ``re + 1j * im`` (1j * im as a complex product)."""
    return complex(re + (0.0 * im - 0.0), 0.0 + (0.0 + im))


@numba.njit(cache=True, nogil=True)
def windowed_samples(z, time_index, deapodize, noise, window):
    """(Re(z[:, time_index] * deapodize) + noise) * window: the real beat samples of a ramp
    (numpy's complex-times-real arithmetic), its thermal noise (or none if ``noise`` is empty)
    and the window."""
    nb, ns = z.shape[0], time_index.shape[0]
    out = np.empty((nb, ns))
    has_noise = noise.shape[0] > 0
    for r in range(nb):
        for k in range(ns):
            v = z[r, time_index[k]]
            s = v.real * deapodize[k] - v.imag * 0.0
            if has_noise:
                s = s + noise[r, k]
            out[r, k] = s * window[k]
    return out


@numba.njit(cache=True, nogil=True)
def bin_powers(x, n_bins, scale, skirts):
    """0.5 |x scale|^2 (numpy's complex-times-real) of the first ``n_bins`` bins, in float32, plus
    the float32 ``skirts`` (none if empty)."""
    nb = x.shape[0]
    out = np.empty((nb, n_bins), np.float32)
    has = skirts.shape[0] > 0
    for r in range(nb):
        for k in range(n_bins):
            v = x[r, k]
            re = v.real * scale - v.imag * 0.0
            im = v.real * 0.0 + v.imag * scale
            p = np.float32(0.5 * (re * re + im * im))
            if has:
                p = p + skirts[r, k]
            out[r, k] = p
    return out
