"""eval.TrajectoryComparison (seed 2, Figs. 8-9) run from a YAML graph on a circle, with
errors of closed form: final errors, ATE, % of the arc length, per-iteration curves."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from impala_eval.comparison.component import TrajectoryComparison
from impala_flow._component import Output, Param, Source
from impala_flow._session import Session
from impala_flow._spec import GraphError
from impala_flow.msgs import Pose2D, Trajectory2D
from impala_flow.testing import run_graph_text

R_M, V_MPS, DURATION_S = 50.0, 5.0, 60  # a circle arc of 300 m
T0_NS = 10**12  # large absolute times, as in a recording
N = DURATION_S + 1  # estimated poses, one a second
K = np.arange(N)
ANGLE, SHIFT = 0.5236, (7.0, -3.0)  # "moved": the truth rotated by 30 deg and shifted


def _circle(t_s: np.ndarray) -> np.ndarray:
    phi = V_MPS * t_s / R_M
    return np.column_stack([R_M * np.sin(phi), R_M * (1 - np.cos(phi)), phi])


def _moved(xyt: np.ndarray) -> np.ndarray:
    c, s = math.cos(ANGLE), math.sin(ANGLE)
    return np.column_stack([c * xyt[:, 0] - s * xyt[:, 1] + SHIFT[0], s * xyt[:, 0] + c * xyt[:, 1] + SHIFT[1],
                            xyt[:, 2] + ANGLE])


def _ns(t_s) -> np.ndarray:
    return T0_NS + np.rint(np.asarray(t_s, float) * 1e9).astype(np.int64)


def _script() -> list[tuple[int, str, Any]]:
    """Truth at 10 Hz; every trajectory sample stamped in the first second, before most of
    the truth (computed at stop()); poses one a second."""
    t10 = np.arange(10 * DURATION_S + 1) / 10.0
    out: list[tuple[int, str, Any]] = [(int(t), "truth", Pose2D(*map(float, p), frame="world"))
                                       for t, p in zip(_ns(t10), _circle(t10), strict=True)]
    t_ns, base = _ns(K), _circle(K.astype(float))
    # "ekf": three iterations over the first 20, 40, then all poses, x error 0.03 k, 0.02 k, 0.01 k
    for i, (n, gain) in enumerate(((20, 0.03), (40, 0.02), (N, 0.01))):
        xyt = base[:n].copy()
        xyt[:, 0] += gain * K[:n]
        out.append((T0_NS + 100_000_000 * (i + 1), "ekf", Trajectory2D(t_ns[:n], xyt)))
    # "lm": one iteration, y error 0.02 m at every pose but the first, and one pose before and
    # one after the truth's span (dropped and counted)
    xyt = base.copy()
    xyt[1:, 1] += 0.02
    lm_t = np.concatenate([[T0_NS - 10**9], t_ns, [T0_NS + (DURATION_S + 1) * 10**9]])
    lm_xyt = np.vstack([[[-5.0, 0.0, 0.0]], xyt, [[0.0, 0.0, 0.0]]])
    out.append((T0_NS + 500_000_000, "lm", Trajectory2D(lm_t, lm_xyt)))
    # "moved": the truth rotated and shifted; its first iteration 1 m further along x
    moved = _moved(base)
    first = moved[:30].copy()
    first[:, 0] += 1.0
    out.append((T0_NS + 100_000_000, "moved", Trajectory2D(t_ns[:30], first)))
    out.append((T0_NS + 200_000_000, "moved", Trajectory2D(t_ns, moved)))
    # dead reckoning: x error 0.05 k
    for k, p in zip(K, base, strict=True):
        out.append((int(t_ns[k]), "baseline", Pose2D(float(p[0] + 0.05 * k), float(p[1]), float(p[2]))))
    return sorted(out, key=lambda s: s[0])


class Mission(Source):
    """The scripted mission above (truth, estimates, dead reckoning)."""

    truth = Output(Pose2D)
    baseline = Output(Pose2D)
    ekf = Output(Trajectory2D)
    isam2 = Output(Trajectory2D)  # connected, never emits
    lm = Output(Trajectory2D)
    moved = Output(Trajectory2D)
    seconds = Param(float, default=DURATION_S, doc="unused")

    def generate(self) -> Iterator[tuple[int, str, Any]]:
        yield from _script()


def _run(params: str, estimates: list[str], baseline: bool = True) -> tuple[dict, TrajectoryComparison]:
    ports = ["truth", *estimates] + (["baseline"] if baseline else [])
    text = f"""
name: comparison
components:
  mission: {{type: t.Mission}}
  compare: {{type: eval.TrajectoryComparison, params: {params}}}
connections:
""" + "".join(f"  - mission.{p} -> compare.{p}\n" for p in ports)
    summary, net = run_graph_text(text, Mission, plugin="t")
    return summary.extra["compare"], net.components["compare"]


def test_closed_form_errors_convergence_and_report(tmp_path):
    out = tmp_path / "report"
    summ, comp = _run(f'{{report: "{out}", estimates: [ekf, isam2, lm], titles: [EKF, iSAM2, LM], align: first}}',
                      ["ekf", "isam2", "lm"])
    m = json.loads((out / "metrics.json").read_text())
    assert summ == {k: round(v, 4) if isinstance(v, float) else v for k, v in m.items()}
    err = 0.01 * K  # the first pose is exact: the "first" alignment changes nothing
    assert m["ekf_ate_rmse_m"] == pytest.approx(math.sqrt(np.mean(err ** 2)), abs=1e-9)
    assert m["ekf_final_err_m"] == pytest.approx(0.01 * (N - 1), abs=1e-9)
    assert m["ekf_mean_err_m"] == pytest.approx(err.mean(), abs=1e-9)
    assert m["ekf_max_err_m"] == pytest.approx(err.max(), abs=1e-9)
    assert (m["ekf_iterations"], m["ekf_poses"], m["ekf_poses_outside_truth"]) == (3, N, 0)
    arc_m = V_MPS * DURATION_S  # the truth's arc over the final trajectory's span (10 Hz chords: 4e-6 short)
    assert m["path_length_m"] == pytest.approx(arc_m, rel=1e-5)
    assert m["ekf_ate_pct"] == pytest.approx(100 * m["ekf_ate_rmse_m"] / arc_m, rel=1e-5)
    # lm: 0.02 m on all poses but the first; the two poses outside the truth's span dropped
    assert m["lm_ate_rmse_m"] == pytest.approx(0.02 * math.sqrt((N - 1) / N), abs=1e-9)
    assert m["lm_final_err_m"] == pytest.approx(0.02, abs=1e-9)
    assert (m["lm_iterations"], m["lm_poses"], m["lm_poses_outside_truth"]) == (1, N + 2, 2)
    assert m["baseline_ate_rmse_m"] == pytest.approx(math.sqrt(np.mean((0.05 * K) ** 2)), abs=1e-9)
    assert m["baseline_final_err_m"] == pytest.approx(0.05 * (N - 1), abs=1e-9)
    assert not [k for k in m if k.startswith("isam2")]  # received nothing: left out, not an error
    assert all(math.isfinite(v) for v in m.values())
    # Fig. 9: (a) mean error of each iteration; (b) mean distance to the final poses; 0 at the end
    c = comp.curves["ekf"]
    assert c["iteration"].tolist() == [1, 2, 3]
    assert c["avg_err"] == pytest.approx([0.03 * K[:20].mean(), 0.02 * K[:40].mean(), 0.01 * K.mean()], abs=1e-9)
    assert c["conv"] == pytest.approx([0.02 * K[:20].mean(), 0.01 * K[:40].mean(), 0.0], abs=1e-9)
    assert c["conv"][-1] == 0.0
    # (c) final error against the distance travelled along the truth
    assert c["dist"] == pytest.approx(V_MPS * K, rel=1e-5)
    assert c["err"] == pytest.approx(err, abs=1e-9)
    assert comp.curves["lm"]["conv"].tolist() == [0.0]
    for png in ("trajectories.png", "convergence.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert (out / png).stat().st_size > 20_000
    report = (out / "report.md").read_text()
    head = ("| estimate | ATE RMSE (m) | ATE (% of path) | final error (m) | end to end (m) | mean error (m) "
            "| iterations | poses |")
    assert head in report
    assert f"| EKF | {m['ekf_ate_rmse_m']:.3f} | {m['ekf_ate_pct']:.3f} | 0.600 | 0.600 | 0.300 | 3 | {N} |" in report
    assert "| LM |" in report and "| dead reckoning |" in report and "| iSAM2 |" not in report
    assert "isam2: received nothing" in report and "lm: 2 of 63 poses outside the truth's time span" in report
    assert "(trajectories.png)" in report and "(convergence.png)" in report


def test_rigid_alignment_removes_a_rotation_and_a_shift(tmp_path):
    m, comp = _run(f'{{report: "{tmp_path}", estimates: [moved], align: rigid}}', ["moved"], baseline=False)
    assert m["moved_ate_rmse_m"] < 1e-6 and m["moved_final_err_m"] < 1e-6 and m["moved_max_err_m"] < 1e-6
    assert m["moved_end_to_end_err_m"] < 1e-6
    c = comp.curves["moved"]  # the final's transform applied to the first iteration: its 1 m shows
    assert c["avg_err"] == pytest.approx([1.0, 0.0], abs=1e-6)
    assert c["conv"] == pytest.approx([1.0, 0.0], abs=1e-9)
    assert not any(k.startswith("baseline") for k in m)
    m_first, _ = _run("{estimates: [moved], align: first}", ["moved"], baseline=False)
    assert m_first["moved_ate_rmse_m"] < 1e-4  # a rigid move is also undone by the first pose


def test_metrics_only_without_report(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    m, _ = _run("{estimates: [lm, ekf]}", ["lm", "ekf"])
    assert m["lm_iterations"] == 1 and m["ekf_iterations"] == 3
    assert list(tmp_path.iterdir()) == []


def test_iterations_beyond_the_row_budget_are_thinned_evenly(tmp_path, monkeypatch):
    monkeypatch.setattr("impala_eval.comparison.component.MAX_ROWS", 50)  # ekf: 20 + 40 + 61 poses
    m, comp = _run(f'{{report: "{tmp_path}", estimates: [ekf]}}', ["ekf"], baseline=False)
    assert m["ekf_iterations"] == 3
    assert m["ekf_ate_rmse_m"] == pytest.approx(math.sqrt(np.mean((0.01 * K) ** 2)), abs=1e-4)
    c = comp.curves["ekf"]
    assert c["subsampled"] and c["iteration"].tolist() == [1, 3]  # the first, then the final one
    assert c["conv"] == pytest.approx([0.02 * K[:20].mean(), 0.0], abs=1e-9)
    assert "ekf: 3 iterations, 2 drawn in Fig. 9" in (tmp_path / "report.md").read_text()


@pytest.mark.parametrize("params, words", [
    ({"estimates": ["truth"]}, "parameter 'estimates': 'truth' is not a valid input name"),
    ({"estimates": ["a b"]}, "parameter 'estimates': 'a b'"),
    ({"estimates": ["ekf", "ekf"]}, "parameter 'estimates': a name is given twice"),
    ({"estimates": ["a", "b"], "titles": ["only one"]}, "parameter 'titles': 1 titles for 2 estimates"),
    ({"estimates": ["a", "b"], "poses": ["c"]}, r"parameter 'poses': \['c'\] not in 'estimates'"),
])
def test_bad_parameters_are_named(params, words):
    with pytest.raises(ValueError, match=words):
        TrajectoryComparison("compare", **params)


def test_bad_parameters_in_a_graph_name_the_component():
    text = """
name: bad
components:
  compare: {type: eval.TrajectoryComparison, params: {estimates: [ekf, lm], titles: [EKF]}}
"""
    with pytest.raises(GraphError, match=r"component 'compare' \(eval.TrajectoryComparison\): parameter 'titles'"):
        Session().load_text(text)
