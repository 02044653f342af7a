"""Trajectory metrics against analytic transforms and a known synthetic truth."""

import json
import math

import numpy as np
import pytest

from impala_eval.evaluator.component import TrajectoryEvaluator
from impala_eval.metrics import interpolate_truth, rigid_align_2d, trajectory_metrics
from impala_flow.msgs import Grid, Pose2D
from impala_flow.testing import ScriptedSource, run_components


def _truth(n=400):
    t = np.arange(n, dtype=np.int64) * 500_000_000 + 10**12  # 2 Hz, large absolute times
    s = np.arange(n) * 0.6
    xyt = np.column_stack([30 * np.sin(s / 30), 20 * (1 - np.cos(s / 25)), np.zeros(n)])
    xyt[:, 2] = np.arctan2(np.gradient(xyt[:, 1]), np.gradient(xyt[:, 0]))
    return t, xyt


def _moved(xyt, dth, tx, ty):
    c, s = math.cos(dth), math.sin(dth)
    out = xyt.copy()
    out[:, 0] = c * xyt[:, 0] - s * xyt[:, 1] + tx
    out[:, 1] = s * xyt[:, 0] + c * xyt[:, 1] + ty
    out[:, 2] = xyt[:, 2] + dth
    return out


def test_rigid_alignment_recovers_an_analytic_transform():
    _, xyt = _truth()
    src = _moved(xyt, 0.7, -12.0, 5.0)
    r, t = rigid_align_2d(src[:, :2], xyt[:, :2])  # should undo it
    c, s = math.cos(-0.7), math.sin(-0.7)
    assert np.allclose(r, [[c, -s], [s, c]], atol=1e-12)
    assert np.allclose(r @ np.array([-12.0, 5.0]) + t, 0.0, atol=1e-9)


def test_ate_of_a_rotated_noisy_copy_equals_the_noise():
    t, xyt = _truth()
    rng = np.random.default_rng(0)
    noise = rng.normal(0, 0.1, (len(t), 2))
    noise -= noise.mean(axis=0)
    est = _moved(xyt, -1.1, 100.0, -40.0)
    est[:, :2] += noise
    m = trajectory_metrics(t, est, t, xyt, "rigid")
    # noise tiny vs the path: the fit barely absorbs it, ATE ~ the noise's RMS
    assert m.ate_rmse_m == pytest.approx(np.sqrt(np.mean(np.sum(noise ** 2, axis=1))), rel=0.02)
    exact = trajectory_metrics(t, _moved(xyt, 2.0, 1.0, 2.0), t, xyt, "first")
    assert exact.ate_max_m < 1e-9 and exact.drift_pct < 1e-9


def test_drift_and_truth_interpolation():
    t, xyt = _truth()
    est = xyt.copy()
    est[:, 0] += np.linspace(0, 2.0, len(t))  # 2 m of drift along x at the end
    m = trajectory_metrics(t[::3], est[::3], t, xyt, "first")
    length = np.sum(np.hypot(*np.diff(xyt[::3, :2], axis=0).T))
    assert m.path_length_m == pytest.approx(length)
    assert m.final_error_m == pytest.approx(est[::3][-1, 0] - xyt[::3][-1, 0], rel=1e-9)
    assert m.drift_pct == pytest.approx(100 * m.final_error_m / length)
    mid = (t[:-1] + t[1:]) // 2
    interp, inside = interpolate_truth(mid, t, xyt)
    assert inside.all() and np.allclose(interp[:, :2], 0.5 * (xyt[:-1, :2] + xyt[1:, :2]))


def test_evaluator_writes_its_report(tmp_path):
    t, xyt = _truth(200)
    est = _moved(xyt, 0.3, 2.0, 1.0)
    base = est.copy()
    base[:, 1] += np.linspace(0, 3, len(t))
    grid = Grid(np.random.default_rng(1).random((300, 300)).astype(np.float32), 0.5, -75.0, -75.0)
    script = [(int(ti), "truth", Pose2D(*p, frame="world")) for ti, p in zip(t, xyt.tolist(), strict=True)]
    script += [(int(ti), "est", Pose2D(*p)) for ti, p in zip(t[1::2], est[1::2].tolist(), strict=True)]
    script += [(int(ti), "base", Pose2D(*p)) for ti, p in zip(t[1::2], base[1::2].tolist(), strict=True)]
    script += [(int(t[5]), "map", grid)]
    script.sort(key=lambda s: s[0])
    ev = TrajectoryEvaluator("eval", report=str(tmp_path / "rep"))
    run_components(ScriptedSource("s", script), ev, connections=[
        "s.truth -> eval.truth", "s.est -> eval.estimate", "s.base -> eval.baseline", "s.map -> eval.map"])
    figures = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert figures["ate_rmse_m"] < 1e-9 and figures["n_poses"] == 100
    assert figures["baseline_ate_rmse_m"] > 0.1 and figures["baseline_drift_pct"] > 0.5
    for png in ("error_vs_distance.png", "trajectory_map.png", "map.png"):
        assert (tmp_path / "rep" / png).stat().st_size > 10_000


def test_report_shows_a_db_map_as_is_and_a_power_map_in_db():
    """slam.RSlam's map is in dB already (A = 10 log10 P): the report must not take its log
    again (that squeezed a 40 dB map into 0-6.6 'dB'); a linear power map is shown in dB."""
    from impala_eval.report import _map_image

    db = np.array([[0.0, 10.0], [25.0, 40.0]], np.float32)
    img, extent = _map_image(Grid(db, 0.5, 0.0, 0.0, "map"), "db")
    assert np.isnan(img[0, 0]) and np.allclose(img[1], [25.0, 40.0]) and img[0, 1] == 10.0
    assert extent == [-0.25, 0.75, -0.25, 0.75]
    power = 10.0 ** (db / 10.0)
    img, _ = _map_image(Grid(power, 0.5, 0.0, 0.0, "map"), "power")
    floor = np.percentile(power, 5)  # its 0 dB: the 5th percentile of the mapped cells
    assert np.nanmax(img) == pytest.approx(10.0 * np.log10(power.max() / floor), rel=1e-5)
