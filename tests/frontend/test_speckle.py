"""SpeckleFilter: multi-look averaging of co-registered turns (seed 1 §2.3)."""

import numpy as np

from impala_flow.msgs import Grid, Pose2D
from impala_flow.testing import CollectingSink, ScriptedSource, run_components
from impala_radar.speckle.component import SpeckleFilter
from impala_radar.speckle.core import enl, threshold_image

CELL_M = 0.2
N_HALF = 150
TARGET_XY = np.array([12.0, -8.0])  # odom frame


def _turns(n, rng, step_m=1.2, yaw_step=0.0):
    """Independent fully developed speckle (exponential intensity, ENL 1) on homogeneous
    clutter plus one point target, seen from poses moving by ``step_m`` per turn."""
    out = []
    for k in range(n):
        pose = Pose2D(step_m * k, 0.0, yaw_step * k, frame="odom")
        data = rng.exponential(1.0, (2 * N_HALF + 1,) * 2).astype(np.float32)
        c, s = np.cos(pose.theta_rad), np.sin(pose.theta_rad)
        d = TARGET_XY - [pose.x_m, pose.y_m]
        tx, ty = c * d[0] + s * d[1], -s * d[0] + c * d[1]
        i, j = int(round(ty / CELL_M)) + N_HALF, int(round(tx / CELL_M)) + N_HALF
        data[i, j] = 1000.0
        out.append(Grid(data, CELL_M, -N_HALF * CELL_M, -N_HALF * CELL_M, "vehicle", pose))
    return out


def _run(grids, **params):
    sink = CollectingSink("sink")
    samples = [(1_000_000_000 * (k + 1), "img", g) for k, g in enumerate(grids)]
    run_components(ScriptedSource("src", samples), SpeckleFilter("sf", **params), sink,
                   connections=["src.img -> sf.image", "sf.filtered -> sink.x"])
    return sink.values()


def test_enl_grows_linearly_with_looks_and_point_keeps_its_peak():
    rng = np.random.default_rng(7)
    grids = _turns(8, rng)  # 1.2 m = 6 cells per turn: exact co-registration
    enls = {}
    for n in (1, 2, 4, 8):
        out = _run(grids, looks=n)[-1]
        region = out.data[N_HALF + 5:N_HALF + 100, N_HALF - 60:N_HALF + 20]  # all 8 looks, no target
        enls[n] = enl(region)
        i, j = (np.round((TARGET_XY - [1.2 * 7, 0]) / CELL_M).astype(int) + N_HALF)[::-1]
        peak = out.data[i, j]
        assert abs(peak - (1000.0 + 0 * n)) < 1.0, peak  # every look has it in the same cell
    print("\nENL by looks:", {n: round(e, 2) for n, e in enls.items()})
    for n, e in enls.items():
        assert abs(e / n - 1.0) <= 0.25


def test_rotated_poses_register_the_target():
    rng = np.random.default_rng(8)
    grids = _turns(4, rng, step_m=1.13, yaw_step=0.05)
    out = _run(grids, looks=4)[-1]
    last = grids[-1]
    k = np.unravel_index(np.argmax(out.data), out.data.shape)
    k_last = np.unravel_index(np.argmax(last.data), last.data.shape)
    assert np.hypot(k[0] - k_last[0], k[1] - k_last[1]) <= 1.0
    # each look rounds the target to its nearest cell, bilinear resampling spreads it: the
    # energy stays within the 3 x 3 neighbourhood
    assert out.data[k[0] - 1:k[0] + 2, k[1] - 1:k[1] + 2].sum() > 0.8 * 1000.0
    region = out.data[N_HALF + 5:N_HALF + 80, N_HALF - 50:N_HALF + 20]
    assert enl(region) >= 0.75 * 4


def test_fmt_threshold():
    x = np.array([[0.0, 1.0, 2.0, 3.0]], np.float32)
    assert np.array_equal(threshold_image(x, "mean", 1.0), [[0, 0, 2, 3]])  # mean of observed = 2
    assert np.array_equal(threshold_image(x, "quantile", 0.5), [[0, 0, 2, 3]])
    assert threshold_image(x, "none", 1.0) is x


def test_mean_of_looks_is_the_numpy_formula_bit_for_bit():
    """The compiled last step of multilook: acc / count where a look saw the cell, else 0."""
    import cv2

    from impala_radar.speckle._jit import mean_of_looks

    rng = np.random.default_rng(6)
    acc = (rng.exponential(1.0, (300, 301)) * rng.integers(0, 2, (300, 301))).astype(np.float32)
    for cnt in (rng.integers(0, 5, acc.shape).astype(np.uint8), rng.integers(0, 300, acc.shape).astype(np.float32)):
        with np.errstate(divide="ignore", invalid="ignore"):
            want = cv2.copyTo(acc / cnt.astype(np.float32), (cnt > 0).view(np.uint8) if cnt.dtype == np.uint8
                              else (cnt > 0).astype(np.uint8))
        out, cnt_f = np.empty_like(acc), np.empty_like(acc)
        mean_of_looks(acc, cnt, out, cnt_f)
        assert np.array_equal(out.view(np.int32), want.view(np.int32))
        assert np.array_equal(cnt_f, cnt.astype(np.float32))
