"""The odometry's robust fit (impala_slam.odometry.fit, compiled) against the library it writes out:
scipy.optimize.least_squares(method="trf", loss="cauchy") on residuals built here from the public
point model (echo_points) reaches the same solution with the same number of evaluations, from a
moving start, a standing one and with the yaw acceleration estimated beside its prior."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from impala_slam.odometry.distortion import Echoes, _packed, echo_points
from impala_slam.odometry.fit import fit_pairs, pair_residuals

T_REF, BETA, SR, SPHI, ACC = 1.0, 0.05, 0.2, 0.005, 0.4


def _echoes(rng, n, t0):
    return Echoes(t0 + rng.uniform(0.0, 1.0, n), rng.uniform(-np.pi, np.pi, n), rng.uniform(5.0, 80.0, n),
                  np.where(rng.random(n) < 0.5, 1.0, -1.0), rng.uniform(12.0, 30.0, n))


def _gaps(p, a, b, yacc):
    """The pairs' gaps along b's radial and tangential axes, over their std, from echo_points."""
    d = echo_points(a, p[0], p[1], T_REF, BETA, ACC, yacc) - echo_points(b, p[0], p[1], T_REF, BETA, ACC, yacc)
    dt = b.t_s - T_REF
    ang = (p[1] + 0.5 * yacc * dt) * dt + b.azimuth_rad
    radial = (d[:, 0] * np.cos(ang) + d[:, 1] * np.sin(ang)) / SR
    tangential = (-d[:, 0] * np.sin(ang) + d[:, 1] * np.cos(ang)) / np.hypot(SR, b.range_m * SPHI)
    return np.concatenate([radial, tangential])


def _pairs(seed, n=150):
    rng = np.random.default_rng(seed)
    a, b = _echoes(rng, n, 0.0), _echoes(rng, n, 1.0)
    b.range_m = a.range_m + rng.normal(0.0, 0.3, n)  # pairs about the same place
    b.range_m[::11] += rng.uniform(5.0, 20.0, b.range_m[::11].size)  # wrong pairs: the loss ignores them
    st = np.hypot(SR, b.range_m * SPHI)
    return a, b, _packed(a, T_REF, BETA, ACC), _packed(b, T_REF, BETA, ACC), st


def _same_solution(x, fun, ref, gaps):
    """The fit's (x, residuals) against scipy's ``ref``: x within what the stopping tolerances (xtol = ftol = 1e-8)
    leave on these random pairs' flat cost (the same iterations, rounded apart: numpy's and numba's trigonometry);
    the residuals those of the public model at that x, and apart from scipy's by what x's difference makes of them
    (to first order, through the model's Jacobian by central differences): residuals of 100-300 move by 1e-6 for
    1e-7 on the speed, and how far the roundings take x apart depends on the CPU's vector units."""
    np.testing.assert_allclose(x, ref.x, rtol=1e-7, atol=1e-6)
    np.testing.assert_allclose(fun, gaps(x), rtol=1e-9, atol=1e-9)
    h = 1e-6 * np.maximum(np.abs(ref.x), 1e-3)
    jac = np.stack([(gaps(ref.x + e) - gaps(ref.x - e)) / (2 * e[k]) for k, e in enumerate(np.diag(h))], axis=1)
    np.testing.assert_allclose(fun - ref.fun, jac @ (x - ref.x), rtol=0, atol=1e-8)


def test_pair_residuals_are_the_gaps_of_the_placed_echoes():
    a, b, pa, pb, st = _pairs(8, 80)
    for p in ([6.0, 0.05], [-1.0, -0.3], [0.0, 0.0], [3.0, 1e-8]):
        out = np.empty(160)
        pair_residuals(np.array(p), pa, pb, SR, st, 0.1, 1.0, out)
        np.testing.assert_allclose(out, _gaps(p, a, b, 0.1), rtol=1e-9, atol=1e-9)
    out = np.empty(161)  # (v, w, yaw acceleration): the prior's residual last
    pair_residuals(np.array([6.0, 0.05, 0.3]), pa, pb, SR, st, 0.1, 0.2, out)
    np.testing.assert_allclose(out[:-1], _gaps([6.0, 0.05], a, b, 0.3), rtol=1e-9, atol=1e-9)
    assert out[-1] == pytest.approx((0.3 - 0.1) / 0.2)


@pytest.mark.parametrize("v0,w0,yacc", [(8.0, 0.1, 0.0), (0.0, 1e-16, 0.0), (5.0, -0.2, 0.3)])
def test_fit_reaches_scipys_solution(v0, w0, yacc):
    a, b, pa, pb, st = _pairs(5)
    ref = least_squares(lambda p: _gaps(p, a, b, yacc), [v0, w0], loss="cauchy", f_scale=2.0, method="trf",
                        x_scale=[1.0, 0.05])
    x, fun, jac, nfev = fit_pairs(np.array([v0, w0]), pa, pb, SR, st, yacc, 1.0, 2.0, np.array([1.0, 0.05]))
    assert nfev == ref.nfev
    _same_solution(x, fun, ref, lambda p: _gaps(p, a, b, yacc))
    np.testing.assert_allclose(jac, ref.jac, rtol=1e-5, atol=1e-5)  # forward differences of each


def test_fit_with_the_yaw_acceleration_and_its_prior():
    a, b, pa, pb, st = _pairs(6)

    def gaps(p):
        return np.append(_gaps(p[:2], a, b, p[2]), (p[2] - 0.1) / 0.2)

    ref = least_squares(gaps, [4.0, 0.05, 0.1], loss="cauchy", f_scale=2.0, method="trf", x_scale=[1.0, 0.05, 0.1])
    x, fun, _, nfev = fit_pairs(np.array([4.0, 0.05, 0.1]), pa, pb, SR, st, 0.1, 0.2, 2.0, np.array([1.0, 0.05, 0.1]))
    assert nfev == ref.nfev
    _same_solution(x, fun, ref, gaps)


def test_pairs_at_rest_keep_the_estimate_at_rest():
    """Two turns of the same echoes (a standing vehicle) from (0, 0): the fit stays there."""
    rng = np.random.default_rng(9)
    a = _echoes(rng, 200, 0.0)
    b = Echoes(a.t_s + 1.0, a.azimuth_rad.copy(), a.range_m + rng.normal(0.0, 0.05, 200), a.ramp.copy(), a.snr_db)
    st = np.hypot(SR, b.range_m * SPHI)
    x, _, _, _ = fit_pairs(np.array([0.0, 0.0]), _packed(a, T_REF, BETA, 0.0), _packed(b, T_REF, BETA, 0.0), SR, st,
                           0.0, 1.0, 2.0, np.array([1.0, 0.05]))
    assert abs(x[0]) < 0.01 and abs(x[1]) < 1e-3
