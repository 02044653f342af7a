"""The simulator's compiled loops (impala_radar.simulator.kernels, synth_kernels) give, bit for bit, what the
numpy formulations they replaced give (np.bincount, np.remainder, np.unwrap, dense ray tests
written out below), so seeded missions did not change; and importing the simulator does not
import numba (the loops compile, or load from the cache, at their first call)."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np

from impala_radar.simulator import kernels, synth_kernels
from impala_radar.simulator.world import World, disc_transmission


def _empty_world(segments) -> World:
    z = np.zeros(0)
    return World(z, z, z, z, np.zeros(0, np.uint8), z, np.asarray(segments, float).reshape(-1, 4))


def test_importing_the_simulator_does_not_import_numba() -> None:
    code = ("import sys; import impala_radar.plugin, impala_radar.simulator.core, impala_radar.simulator.component; "
            "assert 'numba' not in sys.modules, 'numba imported'")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_remainders_are_numpys() -> None:
    rng = np.random.default_rng(3)
    a = np.concatenate([rng.normal(0.0, 300.0, 5000), rng.normal(0.0, 1e5, 5000), [0.0, -0.0, -1e-300, 575.9999]])
    got = synth_kernels.grid_positions(a, 1.0, 576.0)
    np.testing.assert_array_equal(got, a % 576.0)
    assert not np.signbit(got).any()  # -0.0 -> +0.0 as numpy does
    np.testing.assert_array_equal(synth_kernels.wrap_phase32(a), (a % (2.0 * math.pi)).astype(np.float32))


def test_spreading_is_bincounts_sum() -> None:
    """The float32 kernel arguments and the grid sums equal the numpy/bincount formulation."""
    rng = np.random.default_rng(4)
    n, n_beams, width, m_grid = 20000, 12, 6, 576
    row = m_grid + width - 1
    x = rng.uniform(0.0, m_grid, n)
    beam = rng.integers(0, n_beams, n)
    offsets = (np.arange(width) - (width // 2 - 1)).astype(np.float32)
    u_scale, beta = np.float32(2.0 / width), np.float32(2.3 * width)
    arg, base = synth_kernels.kernel_arguments(x, beam, row, offsets, u_scale, beta)
    i0 = np.floor(x)
    u = (offsets[None, :] - (x - i0).astype(np.float32)[:, None]) * u_scale
    np.testing.assert_array_equal(arg, beta * (np.sqrt(np.maximum(np.float32(1.0) - u * u, 0)) - np.float32(1.0)))
    ker = np.exp(arg)
    a_re, a_im = rng.normal(size=n).astype(np.float32), rng.normal(size=n).astype(np.float32)
    b_re, b_im = synth_kernels.spread(base, ker, a_re, a_im, n_beams * row)
    flat = ((beam * row + i0.astype(np.intp))[:, None] + np.arange(width)).ravel()
    np.testing.assert_array_equal(b_re, np.bincount(flat, (ker * a_re[:, None]).ravel(), n_beams * row))
    np.testing.assert_array_equal(b_im, np.bincount(flat, (ker * a_im[:, None]).ravel(), n_beams * row))


def test_walls_hide_what_is_behind_them() -> None:
    """Known cases, then random rays against the dense numpy ray/segment test."""
    w = _empty_world([[5.0, -1.0, 5.0, 1.0]])  # a wall across the x axis at x = 5
    vis = w.visible(np.zeros(2), np.array([10.0, 4.0, 5.0, 10.0]), np.array([0.0, 0.0, 0.5, 5.0]))
    assert vis.tolist() == [False, True, True, True]  # behind; before; on the wall (its own); beside
    rng = np.random.default_rng(5)
    a = rng.uniform(-20, 20, (12, 2))
    seg = np.column_stack([a, a + rng.uniform(-6, 6, (12, 2))])
    p = rng.uniform(-20, 20, (4000, 2))
    q = rng.uniform(-20, 20, (4000, 2))
    rx, ry = (q[:, 0] - p[:, 0])[:, None], (q[:, 1] - p[:, 1])[:, None]
    ax, ay, sx, sy = seg[:, 0], seg[:, 1], seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]
    apx, apy = ax - p[:, 0, None], ay - p[:, 1, None]
    den = rx * sy - ry * sx
    t = (apx * sy - apy * sx) / den
    u = (apx * ry - apy * rx) / den
    t_max = 1.0 - 0.05 / np.maximum(np.hypot(rx, ry), 0.05)
    dense = ~((t > 0.0) & (t < t_max) & (u >= 0.0) & (u <= 1.0)).any(axis=1)
    np.testing.assert_array_equal(_empty_world(seg).visible(p, q[:, 0], q[:, 1]), dense)
    assert 0.2 < dense.mean() < 0.9  # both outcomes are exercised


def test_disc_transmission_multiplies_the_crossed_discs() -> None:
    crown = 10.0 ** (-1.2)
    discs = np.array([[5.0, 0.0, 1.0, 0.0, 6.0, crown], [8.0, 0.0, 1.0, 0.0, 6.0, crown],
                      [0.0, 9.0, 0.5, 0.0, 2.0, 0.0]])
    tr = disc_transmission(np.zeros(2), 1.0, np.array([10.0, 6.5, 0.0, 0.0]), np.zeros(4) + [0, 0, 10, 10],
                           np.array([1.0, 1.0, 1.0, 5.0]), discs)
    assert tr.tolist() == [crown * crown, crown, 0.0, 1.0]  # two crowns; one; a trunk; the ray above it
    rng = np.random.default_rng(6)
    d = np.column_stack([rng.uniform(-20, 20, (40, 2)), rng.uniform(0.3, 3, 40), np.zeros(40),
                         rng.uniform(1, 6, 40), rng.choice([0.0, crown, 0.5], 40)])
    p, q, qz = rng.uniform(-20, 20, (3000, 2)), rng.uniform(-20, 20, (3000, 2)), rng.uniform(0, 6, 3000)
    rx, ry = (q[:, 0] - p[:, 0])[:, None], (q[:, 1] - p[:, 1])[:, None]
    l2 = np.maximum(rx * rx + ry * ry, 1e-12)
    ax, ay = d[:, 0] - p[:, 0, None], d[:, 1] - p[:, 1, None]
    t = (ax * rx + ay * ry) / l2
    ex, ey = ax - t * rx, ay - t * ry
    z_ray = 1.3 + t * (qz[:, None] - 1.3)
    hit = ((t > 0.0) & (t < 1.0 - 0.05 / np.sqrt(l2)) & (ex * ex + ey * ey < d[:, 2] ** 2)
           & (z_ray >= d[:, 3]) & (z_ray <= d[:, 4]))
    dense = np.where(hit, d[:, 5], 1.0).prod(axis=1)
    np.testing.assert_array_equal(disc_transmission(p, 1.3, q[:, 0], q[:, 1], qz, d), dense)
    assert (dense < 1.0).mean() > 0.2


def test_block_spans_are_those_of_np_unwrap() -> None:
    for start in (0.0, 3.0, -3.1, 6.2):
        for sense in (1.0, -1.0):
            d = np.mod(start + sense * 2 * np.pi / 360 * (np.arange(360) + 0.5), 2 * np.pi) - np.pi
            mid, half = kernels.block_spans(d, 8)
            for b in range(45):
                u = np.unwrap(d[8 * b:8 * b + 8])
                assert mid[b] == (0.5 * (u[0] + u[-1]) + math.pi) % (2 * math.pi) - math.pi
                assert half[b] == 0.5 * abs(u[-1] - u[0])


def test_block_candidates_are_the_bearing_window_then_the_near_ones() -> None:
    rng = np.random.default_rng(7)
    bearing = rng.uniform(-np.pi, np.pi, 5000)
    slack = rng.uniform(0.0, 0.2, 5000)
    near = np.nonzero(rng.uniform(size=5000) < 0.05)[0]
    far = np.setdiff1d(np.arange(5000), near)
    far = far[np.argsort(bearing[far], kind="stable")]
    for mid, half, far_slack in [(0.0, 0.05, 0.1), (3.1, 0.05, 0.1), (-3.1, 0.05, 0.2), (1.0, 0.05, 4.0)]:
        got = kernels.block_candidates(far, bearing[far], near, bearing, slack, mid, half, far_slack)
        w = half + far_slack
        if w >= np.pi:
            win = far
        else:
            ranges = [(max(mid - w, -np.pi), min(mid + w, np.pi))]
            ranges += [(mid - w + 2 * np.pi, np.pi)] if mid - w < -np.pi else []
            ranges += [(-np.pi, mid + w - 2 * np.pi)] if mid + w > np.pi else []
            win = np.concatenate([far[np.searchsorted(bearing[far], a):np.searchsorted(bearing[far], b, "right")]
                                  for a, b in ranges])
        j = np.concatenate([win, near])
        want = j[np.abs((bearing[j] - mid + np.pi) % (2 * np.pi) - np.pi) <= half + slack[j]]
        np.testing.assert_array_equal(got, want)
        assert len(want) > 0


def test_tabulated_pattern_gain_is_the_numpy_interpolation() -> None:
    from impala_radar.simulator.antenna import AzimuthPattern

    pat = AzimuthPattern(math.radians(1.8), -25.0)
    rng = np.random.default_rng(5)
    d = np.concatenate([rng.uniform(-0.2, 0.2, 20000), rng.uniform(-math.pi, math.pi, 2000), [0.0, -0.0, 3.0]])
    pos = np.minimum(np.abs(d) * pat._u_per_rad * pat._inv_step, len(pat._g2) - 1.0)
    k = np.minimum(pos.astype(np.intp), len(pat._g2) - 2)
    want = pat._g2[k] * (1.0 - (pos - k)) + pat._g2[k + 1] * (pos - k)
    np.testing.assert_array_equal(kernels.table_gain2(d, pat._u_per_rad, pat._inv_step, pat._g2), want)
    np.testing.assert_array_equal(pat.gain2(d), want)
    assert pat.gain2(d[:3]).tolist() == want[:3].tolist()  # short arrays: the numpy path, the same values
    assert want[-1] == 0.0 and want[-3] == 1.0  # beyond the table nothing; the boresight the peak


def test_the_quick_argsort_with_its_ties_reordered_is_the_stable_one() -> None:
    from impala_radar.simulator.core import _stable_argsort

    rng = np.random.default_rng(5)
    for _ in range(2000):
        n = int(rng.integers(0, 80))
        x = rng.integers(0, max(1, n // 3), n).astype(float) if rng.random() < 0.6 else rng.uniform(-3, 3, n)
        x[rng.random(n) < 0.2] = -0.0  # equal to 0.0
        np.testing.assert_array_equal(_stable_argsort(x, max_ties=int(rng.integers(0, 30))),
                                      np.argsort(x, kind="stable"))
