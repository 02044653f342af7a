"""The robust fit of :func:`~.distortion.estimate_velocity`, compiled (numba, ``cache=True``; imported
at its first call, never with the plugin): the two-turn pair residuals and
scipy.optimize.least_squares's ``method="trf"`` (no bounds, exact trust-region solver, 2-point
Jacobian, ``loss="cauchy"``, ``x_scale``) written out for them, iteration for iteration.

Not scipy.optimize.least_squares itself: its per-call machinery (argument checks, the
VectorFunction and finite-difference wrappers) cost about 5 ms per fit for two or three parameters
and a few hundred residuals, and the same iterations written out in numpy still 2.1 ms (on
RADIATE, most of it the numpy calls' overhead); compiled, 0.5 ms. The iterations are scipy's,
so they stop at the same point to rounding (tests/slam/test_distortion_fit.py compares the
two), and the trust region's small first step around (0, 0) keeps a standing vehicle at rest
as scipy's does. The helpers below follow
scipy/optimize/_lsq/common.py and trf.py (scipy 1.17), whose licence is BSD-3-Clause:
Copyright (c) 2001-2002 Enthought, Inc. 2003, SciPy Developers. All rights reserved (the
licence's full text is in scipy's LICENSE.txt).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["fit_pairs", "pair_residuals"]

EPS = float(np.finfo(float).eps)
_SQRT_EPS = EPS ** 0.5


@numba.njit(cache=True, nogil=True, inline="always")
def _place(e, i, v, w, yacc):  # pragma: no cover - compiled
    """Point (x, y) of echo i of the packed set ``e`` for (v, w, yacc) and its heading th + azimuth
    (:func:`~.distortion.echo_points`; rows of ``e``: dt, a dt^2 / 2, ramp beta, cos azimuth,
    azimuth, range)."""
    dt = e[0, i]
    th = (w + 0.5 * yacc * dt) * dt
    if abs(th) < 1e-6:
        sinc, cosc = 1.0 - th * th / 6.0, 0.5 * th
    else:
        sinc, cosc = math.sin(th) / th, (1.0 - math.cos(th)) / th
    d = v * dt + e[1, i]
    r = e[5, i] + e[2, i] * v * e[3, i]
    a = th + e[4, i]
    return d * sinc + r * math.cos(a), d * cosc + r * math.sin(a), a


@numba.njit(cache=True, nogil=True)
def pair_residuals(p, ea, eb, sr, st, yacc, prior_std, out):  # pragma: no cover - compiled
    """Residuals of the associated pairs (echo i of ``ea`` with echo i of ``eb``) at p = (v, w) or
    (v, w, yaw acceleration): the gap between the placed echoes along the radial, then the
    tangential axis of the second one's heading, over ``sr`` and ``st[i]`` (n radial, n
    tangential); with three parameters a last one, the yaw acceleration's prior
    (p[2] - yacc) / prior_std (else ``yacc`` is the model's fixed yaw acceleration)."""
    n = ea.shape[1]
    joint = p.shape[0] == 3
    alpha = p[2] if joint else yacc
    for i in range(n):
        xa, ya, _ = _place(ea, i, p[0], p[1], alpha)
        xb, yb, ang = _place(eb, i, p[0], p[1], alpha)
        dx, dy = xa - xb, ya - yb
        c, s = math.cos(ang), math.sin(ang)
        out[i] = (dx * c + dy * s) / sr
        out[n + i] = (-dx * s + dy * c) / st[i]
    if joint:
        out[2 * n] = (p[2] - yacc) / prior_std


@numba.njit(cache=True, nogil=True)
def _jacobian(x, f, ea, eb, sr, st, yacc, prior_std, jac):  # pragma: no cover - compiled
    """2-point forward differences, steps sqrt(eps) max(1, |x|) signed like x (scipy's
    approx_derivative)."""
    fi = np.empty_like(f)
    xi = x.copy()
    for k in range(x.shape[0]):
        h = _SQRT_EPS * (1.0 if x[k] >= 0 else -1.0) * max(1.0, abs(x[k]))
        xi[k] = x[k] + h
        pair_residuals(xi, ea, eb, sr, st, yacc, prior_std, fi)
        dx = xi[k] - x[k]
        for j in range(f.shape[0]):
            jac[j, k] = (fi[j] - f[j]) / dx
        xi[k] = x[k]


@numba.njit(cache=True, nogil=True)
def _scale_for_loss(jac, f, f_scale):  # pragma: no cover - compiled
    """scipy's cauchy loss: its cost, and the Jacobian and residuals scaled in place (as its
    scale_for_robust_loss_function)."""
    cost = 0.0
    fs2 = f_scale * f_scale
    for j in range(f.shape[0]):
        z = (f[j] / f_scale) ** 2
        cost += math.log1p(z) * fs2
        t = 1.0 + z
        rho1 = 1.0 / t
        rho2 = -1.0 / t ** 2 / fs2
        js = rho1 + 2.0 * rho2 * f[j] ** 2
        if js < EPS:
            js = EPS
        js = js ** 0.5
        f[j] *= rho1 / js
        for k in range(jac.shape[1]):
            jac[j, k] *= js
    return 0.5 * cost


@numba.njit(cache=True, nogil=True)
def _cost(f, f_scale):  # pragma: no cover - compiled
    s = 0.0
    for j in range(f.shape[0]):
        s += math.log1p((f[j] / f_scale) ** 2)
    return 0.5 * f_scale * f_scale * s


@numba.njit(cache=True, nogil=True)
def _phi(alpha, suf, s, delta):  # pragma: no cover - compiled
    denom = s ** 2 + alpha
    p_norm = np.linalg.norm(suf / denom)
    return p_norm - delta, -np.sum(suf ** 2 / denom ** 3) / p_norm


@numba.njit(cache=True, nogil=True)
def _solve_lsq_trust_region(n, m, uf, s, v, delta, initial_alpha):  # pragma: no cover - compiled
    """More's trust-region step on one SVD of the Jacobian (scipy's solve_lsq_trust_region,
    rtol 0.01, 10 iterations)."""
    suf = s * uf
    full_rank = m >= n and s[-1] > EPS * m * s[0]
    if full_rank:
        p = -(v @ (uf / s))
        if np.linalg.norm(p) <= delta:
            return p, 0.0
    alpha_upper = np.linalg.norm(suf) / delta
    alpha_lower = 0.0
    if full_rank:
        phi, phi_prime = _phi(0.0, suf, s, delta)
        alpha_lower = -phi / phi_prime
    if not full_rank and initial_alpha == 0:
        alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper) ** 0.5)
    else:
        alpha = initial_alpha
    for _ in range(10):
        if alpha < alpha_lower or alpha > alpha_upper:
            alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper) ** 0.5)
        phi, phi_prime = _phi(alpha, suf, s, delta)
        if phi < 0:
            alpha_upper = alpha
        ratio = phi / phi_prime
        alpha_lower = max(alpha_lower, alpha - ratio)
        alpha -= (phi + delta) * ratio / delta
        if abs(phi) < 0.01 * delta:
            break
    p = -(v @ (suf / (s ** 2 + alpha)))
    p *= delta / np.linalg.norm(p)
    return p, alpha


@numba.njit(cache=True, nogil=True)
def fit_pairs(x0, ea, eb, sr, st, yacc, prior_std, f_scale, x_scale):  # pragma: no cover - compiled
    """``least_squares(pair_residuals, x0, loss="cauchy", f_scale=f_scale, method="trf",
    x_scale=x_scale)`` (ftol = xtol = gtol = 1e-8): returns the solution, its residuals, the
    loss-scaled Jacobian there (J^T J: the Gauss-Newton Hessian of the cost) and the number of
    evaluations."""
    nres = 2 * ea.shape[1] + (1 if x0.shape[0] == 3 else 0)
    n = x0.shape[0]
    tol = 1e-8
    x = x0.copy()
    f = np.empty(nres)
    pair_residuals(x, ea, eb, sr, st, yacc, prior_std, f)
    f_true = f.copy()
    jac = np.empty((nres, n))
    _jacobian(x, f, ea, eb, sr, st, yacc, prior_std, jac)
    nfev = 1
    max_nfev = 100 * n
    cost = _scale_for_loss(jac, f, f_scale)
    g = jac.T @ f
    delta = np.linalg.norm(x0 / x_scale)
    if delta == 0:
        delta = 1.0
    alpha = 0.0
    f_new = np.empty(nres)
    while True:
        if np.max(np.abs(g)) < tol or nfev == max_nfev:
            break
        g_h = x_scale * g
        j_h = jac * x_scale
        u, s, vt = np.linalg.svd(j_h, full_matrices=False)
        v = np.ascontiguousarray(vt.T)
        uf = u.T @ f
        actual_reduction = -1.0
        cost_new = cost
        x_new = x
        done = False
        while actual_reduction <= 0 and nfev < max_nfev:
            step_h, alpha = _solve_lsq_trust_region(n, nres, uf, s, v, delta, alpha)
            js = j_h @ step_h
            predicted_reduction = -(0.5 * np.dot(js, js) + np.dot(step_h, g_h))
            step = x_scale * step_h
            x_new = x + step
            pair_residuals(x_new, ea, eb, sr, st, yacc, prior_std, f_new)
            nfev += 1
            step_h_norm = np.linalg.norm(step_h)
            if not np.all(np.isfinite(f_new)):
                delta = 0.25 * step_h_norm
                continue
            cost_new = _cost(f_new, f_scale)
            actual_reduction = cost - cost_new
            if predicted_reduction > 0:
                ratio = actual_reduction / predicted_reduction
            elif predicted_reduction == actual_reduction == 0:
                ratio = 1.0
            else:
                ratio = 0.0
            delta_new = delta
            if ratio < 0.25:
                delta_new = 0.25 * step_h_norm
            elif ratio > 0.75 and step_h_norm > 0.95 * delta:
                delta_new = 2.0 * delta
            ftol_ok = actual_reduction < tol * cost and ratio > 0.25
            xtol_ok = np.linalg.norm(step) < tol * (tol + np.linalg.norm(x))
            if ftol_ok or xtol_ok:
                done = True
                break
            alpha *= delta / delta_new
            delta = delta_new
        if actual_reduction > 0:
            x = x_new
            f[:] = f_new
            f_true[:] = f_new
            cost = cost_new
            _jacobian(x, f, ea, eb, sr, st, yacc, prior_std, jac)
            _scale_for_loss(jac, f, f_scale)
            g = jac.T @ f
        if done:
            break
    return x, f_true, jac, nfev
