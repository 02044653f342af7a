"""The odometry's compiled loops (impala_slam.odometry._jit) against the numpy formulations they
replace: the same counts, bit for bit the same inputs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impala_slam.odometry.distortion import Echoes, _cell_terms, _scores, search_velocity


def _scores_sorted(a, b, vs, ws, t_ref, beta, gate, acc, yacc):
    """The search's counts as numpy computes them: integer cell keys of every echo for every
    candidate (its index in the key's high part), b's sorted, a's found with np.searchsorted."""
    def cells(e):
        x0, y0, x1, y1 = (t[:, None, :] for t in _cell_terms(e, ws, t_ref, beta, acc, yacc))
        v = vs[None, :, None]
        ix = np.floor((x0 + v * x1) * (1.0 / gate)).astype(np.int64) + (1 << 20)
        iy = np.floor((y0 + v * y1) * (1.0 / gate)).astype(np.int64) + (1 << 20)
        cand = np.arange(len(ws) * len(vs), dtype=np.int64).reshape(len(ws), len(vs), 1)
        ramp = (e.ramp > 0).astype(np.int64)[None, None, :]
        return (((cand << 1 | ramp) << 21 | ix) << 21) | iy

    kb = np.sort(cells(b), axis=2).ravel()
    ka = cells(a)
    pos = np.minimum(np.searchsorted(kb, ka), len(kb) - 1)
    return np.count_nonzero(kb[pos] == ka, axis=2).T


def _scene(rng, n, v, w, t0):
    """Echoes of static points seen from a vehicle at (v, w), with clutter and both ramps."""
    pts = rng.uniform(-60.0, 60.0, (n, 2))
    t = t0 + np.sort(rng.uniform(0.0, 0.25, n))
    th = w * t
    d = v * t
    px, py = pts[:, 0] - d * np.cos(0.5 * th), pts[:, 1] - d * np.sin(0.5 * th)
    az = np.arctan2(py, px) - th
    rng_m = np.hypot(px, py) + rng.normal(0.0, 0.05, n)
    ramp = np.where(rng.random(n) < 0.5, 1.0, -1.0)
    return Echoes(t, az, rng_m, ramp, rng.uniform(12.0, 30.0, n))


@pytest.mark.parametrize("seed,gate,acc,yacc", [(1, 0.6, 0.0, 0.0), (2, 0.6, 0.8, 0.1), (3, 0.25, -1.5, 0.0),
                                               (4, 1.7, 0.0, -0.3)])
def test_coincidence_counts_equal_the_sorted_key_search(seed, gate, acc, yacc):
    a = _scene(np.random.default_rng(seed), 150, 6.0, 0.1, 0.0)  # the same points in both turns
    b = _scene(np.random.default_rng(seed), 150, 6.0, 0.1, 0.25)
    vs = np.arange(-3.0, 25.0 + 0.125, 0.25)
    ws = np.arange(-math.radians(30.0), math.radians(30.0) + 1e-9, math.radians(1.0))
    got = _scores(a, b, vs, ws, 0.25, 0.05, gate, acc, yacc)
    ref = _scores_sorted(a, b, vs, ws, 0.25, 0.05, gate, acc, yacc)
    assert got.shape == (len(vs), len(ws))
    assert np.array_equal(got, ref)
    assert ref.max() > 20  # the test has coincidences to count, not only zeros


def test_search_finds_the_motion_that_makes_a_static_scene_coincide():
    """Two turns of the same static points seen from a vehicle moving at 7 m/s, turning at
    6 deg/s: the grid's best candidate is the one nearest that motion."""
    rng = np.random.default_rng(7)
    v, w, period = 7.0, math.radians(6.0), 0.25
    pts = rng.uniform(-70.0, 70.0, (200, 2))
    pts = pts[np.hypot(*pts.T) > 5.0]

    def turn(t0):
        az0 = np.sort(rng.uniform(-np.pi, np.pi, len(pts)))
        t = t0 + (az0 + np.pi) / (2 * np.pi) * period
        th, d = w * t, v * t  # arc of the unicycle from (0, 0, 0) at t = 0
        sinc = np.where(np.abs(th) < 1e-12, 1.0, np.sin(th) / np.where(th == 0, 1.0, th))
        cosc = np.where(np.abs(th) < 1e-12, 0.0, (1 - np.cos(th)) / np.where(th == 0, 1.0, th))
        x, y = d * sinc, d * cosc
        order = rng.permutation(len(pts))  # each echo its own beam time
        p = pts[order]
        dx, dy = p[:, 0] - x, p[:, 1] - y
        az = np.arctan2(dy, dx) - th
        return Echoes(t, az, np.hypot(dx, dy), np.ones(len(t)), np.full(len(t), 20.0))

    a, b = turn(0.0), turn(period)
    best = search_velocity(a, b, period, 0.0, (-3.0, 25.0), (-math.radians(30), math.radians(30)), 0.25,
                           math.radians(1.0), 0.6)
    assert best is not None
    assert abs(best[0] - v) <= 0.25 and abs(best[1] - w) <= math.radians(1.0)


@pytest.mark.parametrize("n", [576, 577, 2, 3, 1])
def test_row_medians_are_numpys_bit_for_bit(n):
    """dB images (negative values too, repeated values of a quantised radar, rows within one bin of
    the radix selection, a row of one value, rows whose two middle values fall in different bins,
    a NaN) against np.median."""
    from impala_slam.odometry._jit import row_medians

    rng = np.random.default_rng(n)
    counts = rng.integers(0, 256, (200, n)).astype(np.float32)  # 8-bit counts, as RADIATE's
    db = np.concatenate([10.0 * np.log10(np.maximum(counts, np.float32(1e-30))) - np.float32(20.0),
                         rng.normal(0.0, 30.0, (200, n)).astype(np.float32),
                         rng.normal(20.0, 0.5, (50, n)).astype(np.float32),  # one bin: selected by the next bits
                         np.round(rng.normal(-20.0, 0.5, (50, n)), 1).astype(np.float32),
                         np.full((2, n), np.float32(-3.5)),
                         np.where(np.arange(n) < n // 2, np.float32(-1.0), np.float32(1e6))[None, :]
                         .astype(np.float32)])
    db[-2, n // 2] = np.nan
    out = np.empty(len(db), np.float32)
    row_medians(db, out)
    ref = np.median(db, axis=1)
    assert out.dtype == ref.dtype
    assert np.array_equal(out, ref, equal_nan=True)
    assert np.array_equal(out.view(np.uint32)[~np.isnan(ref)], ref.view(np.uint32)[~np.isnan(ref)])


def test_local_maxima_are_the_maximum_filters_above_the_threshold():
    """The cells equal to scipy.ndimage.maximum_filter's window maximum (rows wrapping, columns
    repeating their edge) above the threshold, between two columns, in np.nonzero's order."""
    from scipy.ndimage import maximum_filter

    from impala_slam.odometry._jit import local_maxima

    rng = np.random.default_rng(4)
    rel = np.round(rng.normal(0.0, 8.0, (120, 90))).astype(np.float32)  # rounded: plateaus, ties
    rel[0, 10] = rel[119, 10] = 40.0  # a tie across the turn's start
    for rows, cols, k0, k1, thr in [(5, 5, 3, 80, 12.0), (3, 7, 1, 89, 5.5), (120, 5, 0, 90, 12.0),
                                    (4, 6, 2, 50, 0.0)]:
        mx = maximum_filter(rel, (rows, cols), mode=("wrap", "nearest"))
        ok = (rel == mx) & (rel > np.float32(thr))
        ok[:, :k0] = False
        ok[:, k1:] = False
        want = np.nonzero(ok)
        got = local_maxima(rel, rows, cols, k0, k1, np.float32(thr))
        assert len(want[0]) > 0
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])


def _associate_kdtree(pa, pb, ramp_a, ramp_b, gate):
    """Mutual nearest neighbours with scipy's cKDTree: two queries per ramp."""
    from scipy.spatial import cKDTree

    ia_all, ib_all = [], []
    for sign in (1.0, -1.0):
        ma, mb = np.flatnonzero(ramp_a == sign), np.flatnonzero(ramp_b == sign)
        if len(ma) == 0 or len(mb) == 0:
            continue
        da, jb = cKDTree(pb[mb]).query(pa[ma], distance_upper_bound=gate)
        ok = np.isfinite(da)
        ia, ib = ma[ok], mb[jb[ok]]
        _, ja = cKDTree(pa[ma]).query(pb[ib])
        mutual = ma[ja] == ia
        ia_all.append(ia[mutual])
        ib_all.append(ib[mutual])
    return np.concatenate(ia_all), np.concatenate(ib_all)


@pytest.mark.parametrize("seed,gate,falling", [(1, 1.0, True), (2, 0.25, True), (3, 3.0, False)])
def test_mutual_nearest_pairs_are_the_kdtrees(seed, gate, falling):
    from impala_slam.odometry._jit import mutual_nearest

    rng = np.random.default_rng(seed)
    pa = rng.uniform(-80.0, 80.0, (300, 2))
    pb = np.concatenate([pa[:200] + rng.normal(0.0, 0.3, (200, 2)), rng.uniform(-80.0, 80.0, (120, 2))])
    ramp_a = np.where(rng.random(300) < 0.5, 1.0, -1.0) if falling else np.ones(300)
    ramp_b = np.concatenate([ramp_a[:200], np.where(rng.random(120) < 0.5, 1.0, -1.0) if falling else np.ones(120)])
    got = mutual_nearest(pa, pb, ramp_a, ramp_b, gate)
    want = _associate_kdtree(pa, pb, ramp_a, ramp_b, gate)
    assert len(want[0]) > 20
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
