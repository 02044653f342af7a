"""Compiled loops of the simulator's geometry: a turn's (beam, scatterer) pairs with their
occlusion (:func:`block_pairs`), the static pairs' physics around numpy's transcendental
functions (:func:`pair_ranges`, :func:`pair_power`), and the older single-purpose loops that
other paths still use and the new ones are tested against; the synthesis's loops are in
:mod:`.synth_kernels`.

Numba (``cache=True``: compiled once per machine into ``__pycache__``, a few seconds, then
loaded in milliseconds); these modules are imported at the first call of a loop, never by the
plugin's import. The loops do what the numpy expressions they replace did, in the same order
and the same float types, so the spectra are bit for bit those of the numpy formulation: the
exponentials, arctangents, powers and cosines stay numpy's (its SIMD functions round
differently from libm); what is compiled is the arithmetic around them, in one pass instead of
many numpy calls. tests/radar/test_sim_kernels.py and test_sim_turn_kernels.py check each loop
against its formulation.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["remainder", "static_pairs", "segments_clear", "discs_transmission", "block_spans", "block_candidates",
           "table_gain2", "block_pairs", "pair_ranges", "elevation_exponent", "pair_power"]


@numba.njit(cache=True, nogil=True)
def _fmod_remainder(a: float, b: float) -> float:
    r = np.fmod(a, b)  # fmod is exact (numba has no math.fmod)
    if r != 0.0:
        if (b < 0.0) != (r < 0.0):
            r += b
    else:
        r = math.copysign(0.0, b)
    return r


@numba.njit(cache=True, nogil=True, inline="always")
def remainder(a: float, b: float) -> float:
    """numpy's float remainder (npy_divmod): fmod, moved into [0, b) for b > 0. Inlined in the
    callers, the call to fmod out of line (``ramp_echoes`` took 1.5 times as long, 6.3 ms against 4.1
    on a Beynes ramp, with ``a if -b < a < b else fmod(a, b)`` in one expression)."""
    if -b < a < b:  # b > 0 and fmod(a, b) is a itself: npy_divmod's branches without the call
        if a < 0.0:
            return a + b
        return a if a != 0.0 else 0.0
    return _fmod_remainder(a, b)


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
    return remainder(a + math.pi, 2.0 * math.pi) - math.pi


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
            ddmod = remainder(dd + math.pi, 2.0 * math.pi) - math.pi
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
