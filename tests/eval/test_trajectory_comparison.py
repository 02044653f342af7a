"""eval.TrajectoryComparison (seed 2, Figs. 8-9) on trajectories with errors of closed form."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from impala_eval.comparison import TrajectoryComparison
from impala_flow.msgs import Pose2D, Trajectory2D
from impala_flow.testing import ScriptedSource, run_components

R_M = 50.0  # circle radius
V_MPS = 5.0
N = 61  # estimated poses, one a second


def _circle(t_s: np.ndarray) -> np.ndarray:
    phi = V_MPS * t_s / R_M
    return np.column_stack([R_M * np.sin(phi), R_M * (1 - np.cos(phi)), phi])


def _samples(rigid_offset: bool = False):
    t10 = np.arange(0, 10 * (N - 1) + 1) / 10.0
    truth = _circle(t10)
    out = [(int(round(t * 1e9)), "truth", Pose2D(*map(float, p), frame="world"))
           for t, p in zip(t10, truth, strict=True)]
    t1 = np.arange(N, dtype=float)
    t_ns = np.rint(t1 * 1e9).astype(np.int64)
    base = _circle(t1)
    k = np.arange(N)
    end = int(t_ns[-1])
    # three iterations of "ekf": the first n_i poses, x error (3 - i) * 0.01 k (the last = final)
    for i, n_i in enumerate((N // 3, 2 * N // 3, N)):
        xyt = base[:n_i].copy()
        xyt[:, 0] += (3 - i) * 0.01 * k[:n_i] if i < 2 else 0.01 * k[:n_i]
        out.append((int(t_ns[n_i - 1]) if i < 2 else end, "ekf", Trajectory2D(t_ns[:n_i], xyt)))
    # "lm": one iteration, y error 0.02 m at every pose but the first
    xyt = base.copy()
    xyt[1:, 1] += 0.02
    out.append((end, "lm", Trajectory2D(t_ns, xyt)))
    if rigid_offset:  # "moved": the truth rotated by 30 deg and shifted: zero error once aligned rigidly
        c, s = math.cos(0.5236), math.sin(0.5236)
        moved = np.column_stack([c * base[:, 0] - s * base[:, 1] + 7.0, s * base[:, 0] + c * base[:, 1] - 3.0,
                                 base[:, 2] + 0.5236])
        out.append((end, "moved", Trajectory2D(t_ns, moved)))
    return sorted(out, key=lambda s: s[0])


def _run(tmp_path, **params):
    c = TrajectoryComparison("compare", report=str(tmp_path), **params)
    src = ScriptedSource("src", _samples("moved" in params.get("estimates", [])))
    ports = [p for p in ("truth", *params.get("estimates", [])) if p in src.outputs]  # isam2: nothing comes
    run_components(src, c, connections=[f"src.{p} -> compare.{p}" for p in ports])
    return c, json.loads((tmp_path / "metrics.json").read_text())


def test_closed_form_errors_and_convergence(tmp_path):
    c, m = _run(tmp_path, estimates=["ekf", "isam2", "lm"], titles=["EKF", "iSAM2", "LM"], align="first")
    k = np.arange(N)
    err = 0.01 * k
    assert m["ekf_ate_rmse_m"] == pytest.approx(math.sqrt(np.mean(err ** 2)), abs=1e-4)
    assert m["ekf_final_err_m"] == pytest.approx(0.01 * (N - 1), abs=1e-4)
    assert m["ekf_mean_err_m"] == pytest.approx(err.mean(), abs=1e-4)
    assert m["ekf_end_to_end_err_m"] == pytest.approx(0.01 * (N - 1), abs=1e-4)
    chord = 2 * R_M * math.sin(V_MPS / R_M / 2)  # one second of arc
    assert m["path_length_m"] == pytest.approx((N - 1) * chord, abs=0.01)
    assert m["ekf_ate_pct"] == pytest.approx(100 * m["ekf_ate_rmse_m"] / ((N - 1) * chord), abs=1e-3)
    assert m["ekf_iterations"] == 3 and m["ekf_poses"] == N
    assert m["lm_ate_rmse_m"] == pytest.approx(0.02 * math.sqrt((N - 1) / N), abs=1e-4)
    assert "isam2_ate_rmse_m" not in m  # received nothing: left out, not an error
    curves = c.curves["ekf"]
    for i, n_i in enumerate((N // 3, 2 * N // 3)):
        assert curves["avg_err"][i] == pytest.approx(np.mean((3 - i) * 0.01 * k[:n_i]), abs=1e-4)
        assert curves["conv"][i] == pytest.approx(np.mean((2 - i) * 0.01 * k[:n_i]), abs=1e-4)
    assert curves["conv"][-1] == 0.0
    for f in ("trajectories.png", "convergence.png"):
        assert (tmp_path / f).stat().st_size > 10_000
    report = (tmp_path / "report.md").read_text()
    assert "| EKF |" in report and "| LM |" in report and "iSAM2 |" not in report


def test_rigid_alignment_removes_a_rigid_offset(tmp_path):
    _, m = _run(tmp_path, estimates=["moved"], align="rigid")
    assert m["moved_ate_rmse_m"] < 1e-6
    assert m["moved_end_to_end_err_m"] < 1e-6  # the end-to-end error needs no alignment


@pytest.mark.parametrize("params, words", [
    ({"estimates": ["truth"]}, "estimates"),
    ({"estimates": ["a b"]}, "estimates"),
    ({"estimates": ["a", "b"], "titles": ["only one"]}, "titles"),
])
def test_bad_parameters_are_named(params, words):
    with pytest.raises(ValueError, match=words):
        TrajectoryComparison("compare", **params)
