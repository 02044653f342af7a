"""Velocity from the distortion of a rotating radar's scans (seed 1 §4.2, Figs. 13-15).

Each beam of a turn is acquired at its own time from its own pose. With the speed ``V``
and yaw rate ``w`` constant over two consecutive turns, the pose at time ``t`` relative to
the pose at a reference time ``t_ref`` is the arc of the unicycle::

    th(t) = w dt,   x(t) = V dt sinc(th) ...,   dt = t - t_ref     (:func:`arc_poses`)

so a detection (t, azimuth phi, range r) lands on the point ``pose(t) (+) r (cos phi, sin phi)``
of the reference frame: a function of (V, w) alone. A static echo seen in turn k-1 and in
turn k lands on the same point only for the true (V, w): the velocities are the ones that
make the two turns' echoes coincide (Fig. 15). This module holds the pieces on plain
arrays: echo extraction (:func:`extract_echoes`), the point model (:func:`echo_points`)
and the robust two-turn estimate (:func:`estimate_velocity`); the dataflow component,
its Kalman filter and the integration are in :mod:`.odometry`.

Range-Doppler coupling: an FMCW beat frequency carries the echo's Doppler, so a ramp's
apparent range is ``r + s beta v_r`` with ``v_r = -V cos(phi)`` the range rate of a static
echo, ``s`` = +1 on the rising ramp, -1 on the falling one, and ``beta = f0 / (2 dF Fm)``
(twice that for a single-ramp radar whose spectrum axis is the nominal one, Navtech; see
:func:`doppler_beta_s`). The model removes it with the V being estimated
(``doppler=True``); at 8 m/s it is 1.3 m on the IMPALA radar, 0.4 m on Navtech.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from impala_msgs import RadarConfig

__all__ = ["Echoes", "EchoParams", "VelocityEstimate", "arc_poses", "doppler_beta_s", "echo_points",
           "extract_echoes", "estimate_velocity", "search_velocity", "strongest"]


def doppler_beta_s(config: RadarConfig) -> float:
    """Apparent range shift per m/s of range rate on the rising ramp (s): f0 / (2 dF Fm),
    doubled for a single-ramp radar (its nominal axis reads f_r + 2 f_d)."""
    beta = config.f0_hz / (2.0 * config.bandwidth_hz * config.modulation_hz)
    return beta if config.doppler else 2.0 * beta


@dataclass(frozen=True)
class EchoParams:
    """How strong, stable echoes are picked out of a turn."""

    threshold_db: float = 12.0  # above the beam's median (its noise and clutter floor)
    max_echoes: int = 250  # strongest local maxima kept per ramp
    window_beams: int = 0  # local-maximum window in azimuth (0: the antenna aperture)
    window_bins: int = 5  # ... and in range
    range_min_m: float = 3.0
    range_max_m: float = 80.0


@dataclass
class Echoes:
    """Echoes of one turn: beam time (s, relative to an origin), azimuth (rad, vehicle frame),
    measured range (m), ramp sign (+1 rising, -1 falling), strength above the floor (dB)."""

    t_s: np.ndarray
    azimuth_rad: np.ndarray
    range_m: np.ndarray
    ramp: np.ndarray
    snr_db: np.ndarray

    def __len__(self) -> int:
        return len(self.range_m)

    @staticmethod
    def concat(parts: list[Echoes]) -> Echoes:
        return Echoes(*(np.concatenate([getattr(p, f) for p in parts]) for f in
                        ("t_s", "azimuth_rad", "range_m", "ramp", "snr_db")))


def _peaks(rel: np.ndarray, p: EchoParams, config: RadarConfig, n_win_beams: int) -> tuple[np.ndarray, ...]:
    """Local maxima of a (beams sorted by azimuth, bins) image in dB above the beam medians, with
    sub-bin and sub-beam positions (parabola through the peak and its neighbours)."""
    k0 = int(max(1, math.ceil(config.bin_of_range(p.range_min_m))))
    k1 = int(min(rel.shape[1] - 1, math.floor(config.bin_of_range(p.range_max_m))))
    if k1 <= k0:
        return (np.zeros(0, int),) * 2 + (np.zeros(0),) * 3
    from ._jit import local_maxima  # here: numba is imported at the first turn, not with the plugin

    # the maxima of their window (scipy.ndimage.maximum_filter's, rows wrapping round the turn)
    # above the threshold, looked for only where the threshold is passed
    bi, ki = local_maxima(rel, n_win_beams, p.window_bins, k0, k1, rel.dtype.type(p.threshold_db))
    val = rel[bi, ki]
    if len(val) > p.max_echoes:
        keep = np.argpartition(-val, p.max_echoes - 1)[: p.max_echoes]
        keep.sort()
        bi, ki, val = bi[keep], ki[keep], val[keep]
    n = rel.shape[0]
    # parabolic refinement in range and in azimuth (wrapping around the turn)
    left, right = rel[bi, ki - 1], rel[bi, ki + 1]
    den = left - 2.0 * val + right
    dk = np.where(den < 0, 0.5 * (left - right) / np.where(den < 0, den, -1.0), 0.0)
    prev, nxt = rel[(bi - 1) % n, ki], rel[(bi + 1) % n, ki]
    den = prev - 2.0 * val + nxt
    db_ = np.where(den < 0, 0.5 * (prev - nxt) / np.where(den < 0, den, -1.0), 0.0)
    return bi, ki, np.clip(dk, -0.5, 0.5), np.clip(db_, -0.5, 0.5), val


def extract_echoes(t_s: np.ndarray, azimuth_rad: np.ndarray, up: np.ndarray, down: np.ndarray | None,
                   config: RadarConfig, params: EchoParams = EchoParams(), up_rel_db: list | None = None) -> Echoes:
    """Strong, stable echoes of one turn: 2-D local maxima (scipy.ndimage.maximum_filter) of
    each ramp's polar image in dB, ``threshold_db`` above their beam's median, the
    ``max_echoes`` strongest, refined to sub-bin range and sub-beam azimuth.

    ``t_s``/``azimuth_rad`` per beam, in any order and either rotation sense; ``up``/``down``
    (beams, bins) linear power (``down`` None or empty for a power-only radar). ``up_rel_db``, a
    list, receives the ``up`` image in dB above its beam medians (beams in their given order)."""
    from ._jit import row_medians  # here: numba is imported at the first turn, not with the plugin

    order = np.argsort(np.mod(azimuth_rad, 2.0 * np.pi), kind="stable")
    t_s, az = np.asarray(t_s, float)[order], np.unwrap(np.asarray(azimuth_rad, float)[order])
    n = len(order)
    spacing = 2.0 * np.pi / max(n, 1)
    n_win = params.window_beams or max(3, int(round(config.beam_width_rad / spacing)) | 1)
    parts = []
    ramps = [(up, 1.0)] + ([(down, -1.0)] if down is not None and np.size(down) else [])
    for img, sign in ramps:
        img = np.asarray(img, np.float32)[order]
        db = 10.0 * np.log10(np.maximum(img, np.float32(1e-30)))
        med = np.empty(len(db), np.float32)
        row_medians(db, med)  # np.median(db, axis=1) bit for bit, a third of the time
        rel = db - med[:, None]
        if sign > 0 and up_rel_db is not None:  # beams back in their given order
            up_rel_db.append(rel[np.argsort(order, kind="stable")])
        bi, ki, dk, dbeam, val = _peaks(rel, params, config, min(n_win, n))
        if not len(bi):
            continue
        # neighbours' time and azimuth (linear between the peak beam and the next or previous one)
        step = np.where(dbeam >= 0, 1, -1)
        nb = (bi + step) % n
        frac = np.abs(dbeam)
        d_az = np.mod(az[nb] - az[bi] + np.pi, 2.0 * np.pi) - np.pi
        d_t = t_s[nb] - t_s[bi]
        # beams across the start of the turn are a turn apart in time: keep the peak's own
        d_t = np.where(np.abs(d_t) > 3.0 * np.median(np.abs(np.diff(t_s))) + 1e-9, 0.0, d_t)
        parts.append(Echoes(t_s[bi] + frac * d_t, az[bi] + frac * d_az,
                            np.asarray(config.range_of_bin_m(ki + dk), float), np.full(len(bi), sign), val))
    if not parts:
        return Echoes(*(np.zeros(0) for _ in range(5)))
    return Echoes.concat(parts)


def _arc_factors(th: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """cos th, sin th, sin(th)/th and (1 - cos th)/th (series below 1e-6 rad): the chord of an
    arc of unit length turning by th is (sinc, cosc)."""
    small = np.abs(th) < 1e-6
    ths = np.where(small, 1.0, th)
    c, s = np.cos(th), np.sin(th)
    return c, s, np.where(small, 1.0 - th * th / 6.0, s / ths), np.where(small, 0.5 * th, (1.0 - c) / ths)


def arc_poses(v_mps: float, w_radps: float, dt_s: np.ndarray, accel_mps2: float = 0.0, yaw_accel_radps2: float = 0.0
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x, y, theta) after ``dt_s`` at constant speed and yaw rate, from (0, 0, 0); with an
    acceleration the distance along the arc is v dt + a dt^2 / 2, with a yaw acceleration the
    heading w dt + alpha dt^2 / 2 (chord of the constant-rate arc of that length and turn:
    exact when both are 0, second order otherwise)."""
    th = (w_radps + 0.5 * yaw_accel_radps2 * dt_s) * dt_s
    _, _, sinc, cosc = _arc_factors(th)
    d = v_mps * dt_s + 0.5 * accel_mps2 * dt_s * dt_s
    return d * sinc, d * cosc, th


def echo_points(e: Echoes, v_mps: float, w_radps: float, t_ref_s: float, beta_s: float,
                accel_mps2: float = 0.0, yaw_accel_radps2: float = 0.0) -> np.ndarray:
    """Echoes placed in the frame of the pose at ``t_ref_s`` for the velocities (v, w) there,
    (n, 2). ``beta_s`` removes the range-Doppler coupling (0: not); ``accel_mps2`` is a known
    longitudinal acceleration and ``yaw_accel_radps2`` a known yaw acceleration (the filter's),
    so that (v, w) stay the rates at ``t_ref_s`` while they change over the two turns."""
    x, y, th = arc_poses(v_mps, w_radps, e.t_s - t_ref_s, accel_mps2, yaw_accel_radps2)
    r = e.range_m + e.ramp * beta_s * v_mps * np.cos(e.azimuth_rad)
    a = th + e.azimuth_rad
    return np.column_stack([x + r * np.cos(a), y + r * np.sin(a)])


@dataclass
class VelocityEstimate:
    v_mps: float
    w_radps: float
    cov: np.ndarray  # 2x2 over (v, w)
    pairs: int  # associated echo pairs kept (inliers)
    rms_m: float  # RMS distance of the inlier pairs
    yaw_accel_radps2: float = 0.0  # the motion model's yaw acceleration (estimated or given)


def _packed(e: Echoes, t_ref: float, beta: float, acc: float) -> np.ndarray:
    """What placing a turn's echoes for any (v, w) needs that does not depend on them, (6, n): dt,
    a dt^2 / 2, ramp beta (apparent range per m/s of speed, times cos azimuth), cos azimuth,
    azimuth, range (the rows :func:`~.fit.pair_residuals` reads)."""
    dt = e.t_s - t_ref
    return np.stack([dt, 0.5 * acc * dt * dt, e.ramp * beta, np.cos(e.azimuth_rad), e.azimuth_rad, e.range_m])


def _subset(e: Echoes, idx: np.ndarray) -> Echoes:
    return Echoes(e.t_s[idx], e.azimuth_rad[idx], e.range_m[idx], e.ramp[idx], e.snr_db[idx])


def associate(ea: Echoes, eb: Echoes, v: float, w: float, t_ref: float, beta: float,
              gate_m: float, accel_mps2: float = 0.0, yaw_accel_radps2: float = 0.0
              ) -> tuple[np.ndarray, np.ndarray]:
    """Mutual nearest neighbours (same ramp) between the two turns' echoes within ``gate_m``
    (compiled: :func:`~._jit.mutual_nearest`)."""
    from ._jit import mutual_nearest  # here: numba is imported at the first turn, not with the plugin

    pa = echo_points(ea, v, w, t_ref, beta, accel_mps2, yaw_accel_radps2)
    pb = echo_points(eb, v, w, t_ref, beta, accel_mps2, yaw_accel_radps2)
    return mutual_nearest(pa, pb, np.ascontiguousarray(ea.ramp, float), np.ascontiguousarray(eb.ramp, float), gate_m)


def estimate_velocity(ea: Echoes, eb: Echoes, v0: float, w0: float, t_ref_s: float, *, beta_s: float = 0.0,
                      gate_m: float = 2.0, sigma_range_m: float = 0.2, sigma_azimuth_rad: float = 0.005,
                      iterations: int = 3, min_pairs: int = 8, accel_mps2: float = 0.0,
                      yaw_accel_radps2: float = 0.0, yaw_accel_std_radps2: float = 0.0) -> VelocityEstimate | None:
    """(V, w) making turn ``ea``'s echoes coincide with turn ``eb``'s, from (v0, w0).

    Associate (mutual nearest neighbours within a gate that shrinks from ``gate_m``), then
    minimise the radial/tangential residuals scaled by their uncertainties with a robust
    Cauchy loss (scipy.optimize.least_squares's trf, written out and compiled in :mod:`.fit`),
    a few times. The covariance is the Gauss-Newton one at the solution, scaled by the inliers'
    residual variance (at least 1). None when fewer than ``min_pairs`` pairs associate. With
    ``yaw_accel_std_radps2`` the yaw acceleration is estimated too, ``yaw_accel_radps2`` being
    its prior (mean, this std)."""
    v, w = float(v0), float(w0)
    alpha = float(yaw_accel_radps2)
    joint = yaw_accel_std_radps2 > 0
    from .fit import fit_pairs  # here: numba is imported at the first fit, not with the plugin

    fun = jac = None
    for it in range(iterations):
        gate = gate_m * (0.5 ** it) if it < iterations - 1 else max(gate_m * 0.25, 3.0 * sigma_range_m)
        gate = max(gate, 3.0 * sigma_range_m)
        ia, ib = associate(ea, eb, v, w, t_ref_s, beta_s, gate, accel_mps2, alpha)
        if len(ia) < min_pairs:
            return None
        a, b = _subset(ea, ia), _subset(eb, ib)
        pa, pb = _packed(a, t_ref_s, beta_s, accel_mps2), _packed(b, t_ref_s, beta_s, accel_mps2)
        st = np.sqrt(sigma_range_m * sigma_range_m + (b.range_m * sigma_azimuth_rad) ** 2)
        if joint and it == iterations - 1:  # the last, narrowest association only
            sol, fun, jac, _ = fit_pairs(np.array([v, w, alpha]), pa, pb, sigma_range_m, st, yaw_accel_radps2,
                                         yaw_accel_std_radps2, 2.0, np.array([1.0, 0.05, 0.1]))
            v, w, alpha = (float(x) for x in sol)
        else:
            sol, fun, jac, _ = fit_pairs(np.array([v, w]), pa, pb, sigma_range_m, st, alpha, 1.0, 2.0,
                                         np.array([1.0, 0.05]))
            v, w = (float(x) for x in sol)
    r = fun[:-1] if joint else fun  # the prior's residual apart
    n = len(r) // 2
    inl = np.hypot(r[:n], r[n:]) < 3.0
    if int(inl.sum()) < min_pairs:
        return None
    jtj = jac.T @ jac
    try:
        cov = np.linalg.inv(jtj)[:2, :2]
    except np.linalg.LinAlgError:
        return None
    s2 = float(np.sum(r[np.concatenate([inl, inl])] ** 2) / max(2 * int(inl.sum()) - 2, 1))
    cov = cov * max(1.0, s2)
    d = (echo_points(a, v, w, t_ref_s, beta_s, accel_mps2, alpha)
         - echo_points(b, v, w, t_ref_s, beta_s, accel_mps2, alpha))
    rms = float(np.sqrt(np.mean(np.sum(d[inl] ** 2, axis=1))))
    return VelocityEstimate(v, w, cov, int(inl.sum()), rms, alpha)


def strongest(e: Echoes, n: int, range_law_db: float = 40.0) -> Echoes:
    """The ``n`` strongest echoes of each ramp, strength compensated by ``range_law_db`` per
    decade of range (40: the radar equation's R^-4, so that a post at 50 m outranks the
    ground clutter at 6 m: the clutter, as dense at any speed, would favour the speed that
    keeps its band in place, zero)."""
    keep = []
    score = e.snr_db + range_law_db * np.log10(np.maximum(e.range_m, 1.0))
    for sign in (1.0, -1.0):
        m = np.flatnonzero(e.ramp == sign)
        if len(m) > n:
            m = m[np.argsort(-score[m], kind="stable")[:n]]
        keep.append(m)
    return _subset(e, np.sort(np.concatenate(keep)))


def search_velocity(ea: Echoes, eb: Echoes, t_ref_s: float, beta_s: float, v_range: tuple[float, float],
                    w_range: tuple[float, float], v_step: float, w_step: float, gate_m: float,
                    n_strongest: int = 100, prior: tuple[float, float, np.ndarray] | None = None,
                    accel_mps2: float = 0.0, yaw_accel_radps2: float = 0.0) -> tuple[float, float, int] | None:
    """Grid search of (v, w) maximising the coincidences of the strongest echoes: the start
    point of :func:`estimate_velocity` (whose association has a narrow basin: along a hedge
    or a facade parallel to the path, a wrong speed still finds neighbours, the aperture
    problem; isolated echoes only coincide near the truth).

    A coincidence is an echo of ``ea`` falling in a ``gate_m`` cell of the plane that holds
    an echo of the same ramp of ``eb``: every candidate is scored on integer cell keys (a hash
    table per candidate, compiled) rather than one k-d tree per candidate. With a
    ``prior`` (v, w, 2x2 covariance) each score loses half the candidate's squared
    Mahalanobis distance to it (a tie-breaker between look-alike peaks). Returns (v, w,
    coincidences) of the best candidate (ties: the grid's first), None without echoes."""
    a, b = strongest(ea, n_strongest), strongest(eb, n_strongest)
    if not len(a) or not len(b):
        return None
    vs = np.arange(v_range[0], v_range[1] + 0.5 * v_step, v_step)
    ws = np.arange(w_range[0], w_range[1] + 0.5 * w_step, w_step)
    vv, ww = (x.ravel() for x in np.meshgrid(vs, ws, indexing="ij"))
    scores = _scores(a, b, vs, ws, t_ref_s, beta_s, gate_m, accel_mps2, yaw_accel_radps2).ravel()
    value = scores.astype(float)
    if prior is not None:
        d = np.column_stack([vv - prior[0], ww - prior[1]])
        value -= 0.5 * np.einsum("ij,jk,ik->i", d, np.linalg.inv(prior[2]), d)
    k = int(np.argmax(value))
    return float(vv[k]), float(ww[k]), int(scores[k])


def _cell_terms(e: Echoes, ws: np.ndarray, t_ref_s: float, beta_s: float, acc: float, yacc: float = 0.0
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every echo's point for every yaw rate as x0 + v x1, y0 + v y1, (len(ws), n) each: the point
    is linear in v for a given w, so the trigonometry runs once per w."""
    dt = e.t_s[None, :] - t_ref_s
    c, s, sinc, cosc = _arc_factors((ws[:, None] + 0.5 * yacc * dt) * dt)
    ca, sa = np.cos(e.azimuth_rad)[None, :], np.sin(e.azimuth_rad)[None, :]
    cang, sang = c * ca - s * sa, s * ca + c * sa  # cos, sin of th + azimuth
    d0 = 0.5 * acc * dt * dt
    dop = e.ramp[None, :] * beta_s * ca  # range per m/s of speed (range-Doppler coupling)
    x0 = d0 * sinc + e.range_m[None, :] * cang
    y0 = d0 * cosc + e.range_m[None, :] * sang
    x1 = dt * sinc + dop * cang
    y1 = dt * cosc + dop * sang
    return x0, y0, x1, y1


def _scores(a: Echoes, b: Echoes, vs: np.ndarray, ws: np.ndarray, t_ref_s: float, beta_s: float,
            gate_m: float, acc: float, yacc: float = 0.0) -> np.ndarray:
    """Coincidences per candidate, (len(vs), len(ws)): the echoes' cells floor(point / gate_m) for
    each candidate, ``b``'s hashed and ``a``'s looked up, in a compiled loop (:mod:`._jit`)."""
    from ._jit import coincidences  # here: numba is imported at the first search, not with the plugin

    out = np.empty((len(vs), len(ws)), np.int64)
    coincidences(*_cell_terms(a, ws, t_ref_s, beta_s, acc, yacc), (a.ramp > 0).astype(np.int64),
                 *_cell_terms(b, ws, t_ref_s, beta_s, acc, yacc), (b.ramp > 0).astype(np.int64),
                 np.ascontiguousarray(vs, float), 1.0 / gate_m, out)
    return out
