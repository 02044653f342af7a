"""The robust fit of :func:`~.distortion.estimate_velocity`: scipy.optimize.least_squares's
``method="trf"`` (no bounds, exact trust-region solver, 2-point Jacobian, ``loss="cauchy"``)
written out for a small dense problem, step for step the same arithmetic, so the results are
the same bits (tests/slam/test_distortion_fit.py compares the two).

Not scipy.optimize.least_squares itself: its per-call machinery (argument checks, the
VectorFunction and finite-difference wrappers) cost about 5 ms for these two or three parameters
and a few hundred residuals, most of the odometry's time, against well under 1 ms of arithmetic.
The helpers below follow scipy/optimize/_lsq/common.py and trf.py (scipy 1.17), whose licence
is BSD-3-Clause: Copyright (c) 2001-2002 Enthought, Inc. 2003, SciPy Developers. All rights
reserved (the licence's full text is in scipy's LICENSE.txt).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.linalg import norm
from scipy.linalg import svd

__all__ = ["FitResult", "trf_cauchy"]

EPS = np.finfo(float).eps


@dataclass
class FitResult:
    x: np.ndarray
    fun: np.ndarray  # residuals at x
    jac: np.ndarray  # loss-scaled Jacobian at x (J^T J: the Gauss-Newton Hessian of the cost)
    nfev: int


def _loss(f: np.ndarray, f_scale: float, cost_only: bool = False):
    """scipy's cauchy loss with its f_scale, as construct_loss_function applies it."""
    z = (f / f_scale) ** 2
    rho = np.empty((3, f.size))
    rho[0] = np.log1p(z)
    if cost_only:
        return 0.5 * f_scale ** 2 * np.sum(rho[0])
    t = 1 + z
    rho[1] = 1 / t
    rho[2] = -1 / t ** 2
    rho[0] *= f_scale ** 2
    rho[2] /= f_scale ** 2
    return rho


def _scale_for_loss(jac: np.ndarray, f: np.ndarray, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    j_scale = rho[1] + 2 * rho[2] * f ** 2
    j_scale[j_scale < EPS] = EPS
    j_scale **= 0.5
    f *= rho[1] / j_scale
    jac *= j_scale[:, np.newaxis]
    return jac, f


def _with_steps(x0: np.ndarray) -> np.ndarray:
    """x0 and, below it, x0 moved by each 2-point finite-difference step (rows)."""
    sign_x0 = (x0 >= 0).astype(float) * 2 - 1
    h = EPS ** 0.5 * sign_x0 * np.maximum(1.0, np.abs(x0))
    rows = np.tile(x0, (x0.size + 1, 1))
    for i in range(x0.size):
        rows[i + 1, i] = x0[i] + h[i]
    return rows


def _jacobian(rows: np.ndarray, f_rows: np.ndarray) -> np.ndarray:
    """2-point forward differences, steps sqrt(eps) max(1, |x|) (scipy's approx_derivative),
    from the residuals of the rows of :func:`_with_steps`."""
    x0, n = rows[0], rows.shape[1]
    jt = np.empty((n, f_rows.shape[1]))
    for i in range(n):
        jt[i] = (f_rows[i + 1] - f_rows[0]) / (rows[i + 1, i] - x0[i])
    return jt.T


def _solve_lsq_trust_region(n, m, uf, s, v, delta, initial_alpha=None, rtol=0.01, max_iter=10):
    """More's trust-region step on one SVD of the Jacobian (scipy's solve_lsq_trust_region)."""
    def phi_and_derivative(alpha, suf, s, delta):
        denom = s ** 2 + alpha
        p_norm = norm(suf / denom)
        phi = p_norm - delta
        phi_prime = -np.sum(suf ** 2 / denom ** 3) / p_norm
        return phi, phi_prime

    suf = s * uf
    if m >= n:
        threshold = EPS * m * s[0]
        full_rank = s[-1] > threshold
    else:
        full_rank = False
    if full_rank:
        p = -v.dot(uf / s)
        if norm(p) <= delta:
            return p, 0.0
    alpha_upper = norm(suf) / delta
    if full_rank:
        phi, phi_prime = phi_and_derivative(0.0, suf, s, delta)
        alpha_lower = -phi / phi_prime
    else:
        alpha_lower = 0.0
    if initial_alpha is None or not full_rank and initial_alpha == 0:
        alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper) ** 0.5)
    else:
        alpha = initial_alpha
    for _ in range(max_iter):
        if alpha < alpha_lower or alpha > alpha_upper:
            alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper) ** 0.5)
        phi, phi_prime = phi_and_derivative(alpha, suf, s, delta)
        if phi < 0:
            alpha_upper = alpha
        ratio = phi / phi_prime
        alpha_lower = max(alpha_lower, alpha - ratio)
        alpha -= (phi + delta) * ratio / delta
        if np.abs(phi) < rtol * delta:
            break
    p = -v.dot(suf / (s ** 2 + alpha))
    p *= delta / norm(p)
    return p, alpha


def _update_tr_radius(delta, actual_reduction, predicted_reduction, step_norm, bound_hit):
    if predicted_reduction > 0:
        ratio = actual_reduction / predicted_reduction
    elif predicted_reduction == actual_reduction == 0:
        ratio = 1
    else:
        ratio = 0
    if ratio < 0.25:
        delta = 0.25 * step_norm
    elif ratio > 0.75 and bound_hit:
        delta *= 2.0
    return delta, ratio


def _check_termination(df, f, dx_norm, x_norm, ratio, ftol, xtol):
    ftol_satisfied = df < ftol * f and ratio > 0.25
    xtol_satisfied = dx_norm < xtol * (xtol + x_norm)
    if ftol_satisfied and xtol_satisfied:
        return 4
    if ftol_satisfied:
        return 2
    if xtol_satisfied:
        return 3
    return None


def _evaluate_quadratic(jac, g, s):
    js = jac.dot(s)
    return 0.5 * np.dot(js, js) + np.dot(s, g)


def trf_cauchy(fun: Callable[[np.ndarray], np.ndarray], x0, f_scale: float, x_scale,
               ftol: float = 1e-8, xtol: float = 1e-8, gtol: float = 1e-8) -> FitResult:
    """``least_squares(f, x0, loss="cauchy", f_scale=f_scale, method="trf", x_scale=x_scale)``
    for a dense, unbounded problem: the same iterations and the same result. ``fun`` takes
    parameter sets as rows (k, n) and returns their residuals as rows (k, m): each trial point
    is evaluated with its finite-difference neighbours in one call."""
    x0 = np.atleast_1d(x0).astype(float)
    scale = np.asarray(x_scale, dtype=float)
    scale_inv = 1 / scale
    rows = _with_steps(x0)
    f_rows = fun(rows)
    f = f_rows[0].copy()
    jac = _jacobian(rows, f_rows)
    x = x0.copy()
    f_true = f.copy()
    nfev = 1
    m, n = jac.shape
    max_nfev = x0.size * 100
    rho = _loss(f, f_scale)
    cost = 0.5 * np.sum(rho[0])
    jac, f = _scale_for_loss(jac, f, rho)
    g = jac.T.dot(f)
    delta = norm(x0 * scale_inv)
    if delta == 0:
        delta = 1.0
    alpha = 0.0
    status = None
    while True:
        g_norm = norm(g, ord=np.inf)
        if g_norm < gtol:
            status = 1
        if status is not None or nfev == max_nfev:
            break
        d = scale
        g_h = d * g
        j_h = jac * d
        u, s, vt = svd(j_h, full_matrices=False, check_finite=False)  # residuals of finite echoes are finite
        v = vt.T
        uf = u.T.dot(f)
        actual_reduction = -1
        while actual_reduction <= 0 and nfev < max_nfev:
            step_h, alpha = _solve_lsq_trust_region(n, m, uf, s, v, delta, initial_alpha=alpha)
            predicted_reduction = -_evaluate_quadratic(j_h, g_h, step_h)
            step = d * step_h
            x_new = x + step
            rows = _with_steps(x_new)  # the Jacobian's points too, should the step be accepted
            f_rows = fun(rows)
            f_new = f_rows[0]
            nfev += 1
            step_h_norm = norm(step_h)
            if not np.all(np.isfinite(f_new)):
                delta = 0.25 * step_h_norm
                continue
            cost_new = _loss(f_new, f_scale, cost_only=True)
            actual_reduction = cost - cost_new
            delta_new, ratio = _update_tr_radius(delta, actual_reduction, predicted_reduction, step_h_norm,
                                                 step_h_norm > 0.95 * delta)
            status = _check_termination(actual_reduction, cost, norm(step), norm(x), ratio, ftol, xtol)
            if status is not None:
                break
            alpha *= delta / delta_new
            delta = delta_new
        if actual_reduction > 0:
            x = x_new
            f = f_new.copy()
            f_true = f.copy()
            cost = cost_new
            jac = _jacobian(rows, f_rows)
            rho = _loss(f, f_scale)
            jac, f = _scale_for_loss(jac, f, rho)
            g = jac.T.dot(f)
    return FitResult(x, f_true, jac, nfev)
