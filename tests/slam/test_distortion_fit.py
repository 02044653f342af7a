"""The odometry's robust fit (impala_slam.odometry.fit.trf_cauchy) against the library it writes out:
scipy.optimize.least_squares(method="trf", loss="cauchy") gives the same bits, on a curve fit with
outliers and on the two-turn echo residuals of the odometry (echoes placed by the same code here)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from impala_slam.odometry.distortion import Echoes, _residuals_rows
from impala_slam.odometry.fit import trf_cauchy


def _same(fit, ref):
    assert np.array_equal(fit.x, ref.x)
    assert np.array_equal(fit.fun, ref.fun)
    assert np.array_equal(fit.jac, ref.jac)


@pytest.mark.parametrize("x0", [[1.0, -0.5, 0.2], [0.0, 0.0, 0.0], [1e-15, 0.0, 3.0]])
def test_curve_with_outliers_same_bits_as_scipy(x0):
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 4.0, 120)
    y = 2.0 * np.exp(-0.7 * t) + 0.3 * np.sin(3.0 * t) + rng.normal(0.0, 0.02, t.size)
    y[::9] += rng.uniform(1.0, 3.0, y[::9].size)  # outliers

    def one(p):
        return p[0] * np.exp(-p[1] * t) + p[2] * np.sin(3.0 * t) - y

    def rows(ps):
        return np.stack([one(p) for p in ps])

    ref = least_squares(one, x0, loss="cauchy", f_scale=0.1, method="trf", x_scale=[1.0, 0.1, 0.5])
    fit = trf_cauchy(rows, x0, 0.1, [1.0, 0.1, 0.5])
    _same(fit, ref)
    assert abs(fit.x[0] - 2.0) < 0.05 and abs(fit.x[1] - 0.7) < 0.05  # the outliers are ignored


def _echoes(rng, n, t0):
    return Echoes(t0 + rng.uniform(0.0, 1.0, n), rng.uniform(-np.pi, np.pi, n), rng.uniform(5.0, 80.0, n),
                  np.where(rng.random(n) < 0.5, 1.0, -1.0), rng.uniform(12.0, 30.0, n))


@pytest.mark.parametrize("v0,w0,yacc", [(8.0, 0.1, 0.0), (0.0, 1e-16, 0.0), (5.0, -0.2, 0.3)])
def test_echo_residuals_same_bits_as_scipy(v0, w0, yacc):
    rng = np.random.default_rng(5)
    a, b = _echoes(rng, 150, 0.0), _echoes(rng, 150, 1.0)
    b.range_m = a.range_m + rng.normal(0.0, 0.3, 150)  # pairs about the same place
    args = (a, b, 1.0, 0.05, 0.2, 0.005, 0.4, yacc)

    def one(p):
        return _residuals_rows(np.asarray(p)[None, :], *args)[0]

    ref = least_squares(one, [v0, w0], loss="cauchy", f_scale=2.0, method="trf", x_scale=[1.0, 0.05])
    fit = trf_cauchy(lambda ps: _residuals_rows(ps, *args), [v0, w0], 2.0, [1.0, 0.05])
    _same(fit, ref)


def test_residual_rows_are_the_gaps_of_the_placed_echoes_row_by_row():
    """Several parameter sets at once give each set's residuals alone, bit for bit; and they are the
    gaps between the pairs' placed points (echo_points) along b's radial and tangential axes."""
    from impala_slam.odometry.distortion import echo_points

    rng = np.random.default_rng(8)
    a, b = _echoes(rng, 80, 0.0), _echoes(rng, 80, 1.0)
    ps = np.array([[6.0, 0.05], [6.0 + 1e-8, 0.05], [-1.0, -0.3], [0.0, 0.0]])
    rows = _residuals_rows(ps, a, b, 1.0, 0.05, 0.2, 0.005, 0.4, 0.1)
    for p, row in zip(ps, rows, strict=True):
        assert np.array_equal(row, _residuals_rows(p[None, :], a, b, 1.0, 0.05, 0.2, 0.005, 0.4, 0.1)[0])
        d = echo_points(a, *p, 1.0, 0.05, 0.4, 0.1) - echo_points(b, *p, 1.0, 0.05, 0.4, 0.1)
        dt = b.t_s - 1.0
        ang = (p[1] + 0.05 * dt) * dt + b.azimuth_rad
        radial = (d[:, 0] * np.cos(ang) + d[:, 1] * np.sin(ang)) / 0.2
        tangential = (-d[:, 0] * np.sin(ang) + d[:, 1] * np.cos(ang)) / np.hypot(0.2, b.range_m * 0.005)
        np.testing.assert_allclose(row, np.concatenate([radial, tangential]), rtol=1e-9, atol=1e-9)
