"""The evaluator against a GPS truth as recorded: 20 Hz fixes written twice, a hole in the log,
the heading known only while moving (course over ground), a 4 Hz estimate with its own hole."""

import json
import logging
import math

import numpy as np
import pytest

from impala_eval.evaluator.component import TrajectoryEvaluator
from impala_eval.metrics import twist_errors
from impala_eval.report import find_gaps, format_metrics, gap_summary
from impala_flow.msgs import Pose2D, Twist2D
from impala_flow.testing import ScriptedSource, run_components

from . import gps_drive as g


def _no_nan(text: str) -> dict:
    def refuse(c: str) -> float:
        raise AssertionError(f"metrics.json holds {c}")
    return json.loads(text, parse_constant=refuse)


def _run(truth, est, tmp_path, twist=None, **params):
    """The evaluator as a graph runs it: truth and estimate (and twist) scripted by time."""
    script = [(t, "truth", p) for t, p in truth]
    script += [(int(t), "est", Pose2D(*p)) for t, p in zip(est[0], est[1].tolist(), strict=True)]
    conns = ["s.truth -> eval.truth", "s.est -> eval.estimate"]
    if twist is not None:
        script += [(int(t), "twist", Twist2D(float(v), float(w))) for t, v, w in zip(*twist, strict=True)]
        conns.append("s.twist -> eval.twist")
    script.sort(key=lambda s: s[0])
    ev = TrajectoryEvaluator("eval", report=str(tmp_path / "rep"), **params)
    run_components(ScriptedSource("s", script), ev, connections=conns)
    return ev


def test_no_false_gap_with_a_20hz_gps_and_its_repeats_real_gaps_in_one_line(tmp_path, caplog):
    d = g.drive()
    t, xyt, known = g.gps(d)  # every fix twice, no fix for 2 s from t0 + 100 s
    assert np.count_nonzero(np.diff(t) == 0) == len(t) // 2  # the median interval is 0
    est = g.estimate(d)  # no pose for 1.6 s from t0 + 40 s
    with caplog.at_level(logging.INFO):
        ev = _run(g.truth_poses(t, xyt, known), est, tmp_path)
    gaps = ev.figures["gaps"]
    t0 = g.T0_NS * 1e-9
    assert sorted(gaps) == ["estimate", "truth"]
    # the fixes at exactly 100.0 and 102.0 s stay; the 4 Hz poses at 40.0 and 41.75 s
    assert len(gaps["truth"]) == 1 and gaps["truth"][0] == pytest.approx([t0 + 100.0, t0 + 102.0], abs=1e-5)
    assert len(gaps["estimate"]) == 1 and gaps["estimate"][0] == pytest.approx([t0 + 40.0, t0 + 41.75], abs=1e-5)
    assert ev.figures["gap_total_s"] == pytest.approx(3.75, abs=1e-5)
    # 7 estimated poses (100.25 ... 101.75 s) lie in the truth's hole: left out, counted
    assert ev.figures["n_poses_in_truth_gaps"] == 7
    warnings = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1 and "\n" not in warnings[0] and len(warnings[0]) < 250, warnings
    assert "estimate 1 gap (1.75 s" in warnings[0] and "truth 1 gap (2.00 s" in warnings[0]
    repeated = [r.getMessage() for r in caplog.records if "repeat" in r.getMessage()]
    assert repeated == [f"truth: {len(t) // 2} samples repeat an earlier one's time stamp, the first of each kept"]
    figures = _no_nan((tmp_path / "rep" / "metrics.json").read_text())
    assert figures["n_poses"] == len(est[0]) - 7


def test_find_gaps_ignores_jitter_and_near_repeats_and_summarises_many_gaps_in_one_line():
    rng = np.random.default_rng(3)
    t = 10**18 + np.cumsum(rng.integers(45_000_000, 55_000_000, 2000))  # 20 Hz with 10 % jitter
    near = np.sort(np.concatenate([t, t + 1_000_000]))  # each fix again 1 ms later
    assert find_gaps(t) == [] and find_gaps(near) == [] and find_gaps(np.repeat(t, 3)) == []
    holes = np.delete(t, np.arange(10, 2000, 4))  # 498 missing fixes: 498 gaps of 2 periods...
    assert find_gaps(holes) == []  # ... not more than 3 periods: no gap
    gappy = np.delete(t, np.concatenate([np.arange(k, k + 5) for k in range(10, 1990, 40)]))
    gaps = find_gaps(gappy)
    assert len(gaps) == 50
    line = gap_summary({"truth": gaps})
    assert "\n" not in line and len(line) < 120 and line.startswith("truth 50 gaps (")
    assert "np.float64" not in line and "np.float64" not in repr(gaps)


def test_unknown_truth_headings_score_positions_only(tmp_path, caplog):
    """Estimate = the true poses in another frame: every figure is 0, though the GPS's
    placeholder headings (0 at rest) are far from the estimate's there."""
    d = g.drive()
    t, xyt, known = g.gps(d, noise_m=0.0, white_m=0.0, heading_noise_deg=0.0, hole_s=None, repeat=False)
    est = g.estimate(d, scale=1.0, yaw_per_m=0.0, noise_m=0.0, hole_s=None)
    moving = d.speed_mps[:: g.EST_EVERY] > 1.0  # the truth heading at each estimate's time (same stamps)
    assert not moving[0] and not moving.all()
    v_est = d.speed_mps[:: g.EST_EVERY]
    w_est = np.gradient(d.xyt[:: g.EST_EVERY, 2], est[0] * 1e-9)
    with caplog.at_level(logging.INFO):
        ev = _run(g.truth_poses(t, xyt, known), est, tmp_path, twist=(est[0], v_est, w_est), align="first",
                  pairs=True, twist_window_s=0.25)
    f = ev.figures
    assert f["n_heading_unknown"] == np.count_nonzero(~moving)
    assert f["first_aligned_pose"] == int(np.argmax(moving))
    assert f["n_pairs_heading_unknown"] == np.count_nonzero(~(moving[1:] & moving[:-1]))
    assert f["n_pairs"] == np.count_nonzero(moving[1:] & moving[:-1])
    for key in ("ate_rmse_m", "ate_max_m", "heading_rmse_deg", "drift_pct", "final_rot_err_rad", "rel_err_pct",
                "pair_trans_err_max_m", "pair_rot_err_max_deg"):
        assert f[key] < 1e-6, key
    # the yaw rate only where the truth heading is known at both ends of the 0.25 s window
    h = 125_000_000
    sp = np.interp((est[0] - d.t_ns[0]).astype(float), (d.t_ns - d.t_ns[0]).astype(float), d.speed_mps)
    ends_known = (np.interp((est[0] - h - d.t_ns[0]).astype(float), (d.t_ns - d.t_ns[0]).astype(float),
                            d.speed_mps) > 1.0) & (np.interp((est[0] + h - d.t_ns[0]).astype(float),
                                                             (d.t_ns - d.t_ns[0]).astype(float), d.speed_mps) > 1.0)
    inside = (est[0] - h >= t[0]) & (est[0] + h <= t[-1])
    assert f["twist_yaw_rate_n"] == np.count_nonzero(ends_known & inside) and f["twist_heading_unknown"] > 0
    assert sp.shape == est[0].shape
    assert abs(f["yaw_rate_err_mean_dps"]) < 0.1 and f["speed_err_abs_median_mps"] < 0.05
    text = "\n".join(r.getMessage() for r in caplog.records)
    assert f"truth heading unknown at {f['n_heading_unknown']} of {f['n_poses']} poses" in text
    _no_nan((tmp_path / "rep" / "metrics.json").read_text())


def test_a_truth_without_any_heading_refuses_first_alignment_and_scores_positions(tmp_path, caplog):
    d = g.drive(duration_s=60.0, stop_at_s=50.0)
    t, xyt, known = g.gps(d, noise_m=0.0, white_m=0.0, hole_s=None, known=False)
    est = g.estimate(d, scale=1.0, yaw_per_m=0.0, noise_m=0.0, hole_s=None)
    truth = g.truth_poses(t, xyt, known)
    with caplog.at_level(logging.WARNING):
        ev = _run(truth, est, tmp_path / "first", align="first")
    assert ev.metrics is None and not (tmp_path / "first" / "rep").exists()
    msgs = [r.getMessage() for r in caplog.records]
    assert len(msgs) == 1 and msgs[0].startswith("no report: align: first needs a known truth heading")
    ev = _run(truth, est, tmp_path, align="rigid", pairs=True)
    f = _no_nan((tmp_path / "rep" / "metrics.json").read_text())
    assert f["ate_rmse_m"] < 1e-6 and f["n_heading_unknown"] == f["n_poses"] == len(est[0])
    for key in ("heading_rmse_deg", "rel_err_pct", "drift_pct", "final_rot_err_rad", "pair_rot_err_mean_deg"):
        assert f[key] is None, key
    assert f["n_pairs"] == 0 and f["rel_err_segments"] == 0
    assert "ate_rmse_m" in ev.summary() and "rel_err_pct" not in ev.summary()


def test_twist_without_truth_heading_scores_unsigned_speed_only():
    d = g.drive(duration_s=40.0, stop_at_s=30.0)
    t, xyt, _ = g.gps(d, noise_m=0.0, white_m=0.0, hole_s=None, repeat=False)
    tt = d.t_ns[5:-5:5]
    v = -np.interp((tt - t[0]).astype(float), (t - t[0]).astype(float), d.speed_mps)  # reversing?
    tw = twist_errors(tt, v, np.zeros(len(tt)), t, xyt, 0.5, np.zeros(len(t), bool))
    assert len(tw.yaw_rate_err_dps) == 0 and tw.figures()["yaw_rate_err_mean_dps"] is None
    assert tw.figures()["twist_heading_unknown"] == len(tt)
    # unsigned truth speed takes the estimate's sign: a window's chord over its duration
    assert np.max(np.abs(tw.speed_err_mps)) < 0.1


def _kitti_run(tmp_path, **estimate):
    d = g.drive(straight=True, duration_s=150.0, stop_at_s=200.0)  # rest 10 s, then straight on
    t, xyt, known = g.gps(d, noise_m=0.0, white_m=0.0, heading_noise_deg=0.0, hole_s=None)
    est = g.estimate(d, noise_m=0.0, hole_s=None, **estimate)
    return d, _run(g.truth_poses(t, xyt, known), est, tmp_path, align="rigid")


def test_kitti_drift_of_a_scale_error_is_the_scale_error(tmp_path):
    d, ev = _kitti_run(tmp_path, scale=1.02, yaw_per_m=0.0)
    f = ev.figures
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(d.xyt[:: g.EST_EVERY, :2], axis=0).T))])
    moving = d.speed_mps[:: g.EST_EVERY] > 1.0
    for L in (100, 200, 300, 400, 500, 600, 700, 800):
        assert f[f"rel_err_{L}m_pct"] == pytest.approx(2.0, rel=1e-6)
        # segments start at every pose where the truth heading is known and L m still lie ahead
        assert f[f"rel_err_{L}m_segments"] == pytest.approx(np.count_nonzero(moving & (s[-1] - s >= L)), abs=1)
    assert f["rel_err_pct"] == pytest.approx(2.0, rel=1e-6) and f["rel_err_per_100m_pct"] == pytest.approx(2.0)
    summary = ev.summary()
    assert summary["rel_err_800m_pct"] == 2.0 and summary["rel_err_pct"] == 2.0
    block = format_metrics(f)
    assert "drift per segment length: 100 m 2.00 % (n=" in block and ", 800 m 2.00 % (n=" in block
    assert "drift 100-800 m" in block and "ATE RMSE / path" in block
    assert summary["ate_pct"] == pytest.approx(100 * f["ate_rmse_m"] / f["path_length_m"], abs=1e-3)


def test_kitti_drift_of_a_heading_drift_is_the_chord_of_its_arc(tmp_path):
    k = 1e-4  # rad per metre: the estimate drives an arc of curvature k where the truth goes straight
    _, ev = _kitti_run(tmp_path, scale=1.0, yaw_per_m=k)
    def chord_pct(length):  # the end of an arc of that length against the straight line's, in %
        arc = np.array([math.sin(k * length) / k, (1 - math.cos(k * length)) / k])
        return 100 * np.hypot(*(arc - [length, 0.0])) / length

    for L in (100, 400, 800):  # a segment ends at the first pose L m on or further: up to one 2 m step
        assert chord_pct(L) * (1 - 1e-6) <= ev.figures[f"rel_err_{L}m_pct"] <= chord_pct(L + 2.0)


def _compare(truth, est, tmp_path, **params):
    from impala_eval.comparison.component import TrajectoryComparison

    script = [(t, "truth", p) for t, p in truth]
    script += [(int(t), "est", Pose2D(*p)) for t, p in zip(est[0], est[1].tolist(), strict=True)]
    script.sort(key=lambda s: s[0])
    comp = TrajectoryComparison("compare", estimates=["odo"], poses=["odo"], report=str(tmp_path), **params)
    run_components(ScriptedSource("s", script), comp, connections=["s.truth -> compare.truth",
                                                                   "s.est -> compare.odo"])
    return comp


def test_comparison_aligns_first_on_the_first_known_truth_heading(tmp_path, caplog):
    d = g.drive(duration_s=60.0, stop_at_s=50.0)
    t, xyt, known = g.gps(d, noise_m=0.0, white_m=0.0, heading_noise_deg=0.0, hole_s=None)
    est = g.estimate(d, scale=1.0, yaw_per_m=0.0, noise_m=0.0, hole_s=None)  # the truth in another frame
    comp = _compare(g.truth_poses(t, xyt, known), est, tmp_path / "some", align="first")
    f = comp.figures
    assert f["odo_ate_rmse_m"] < 1e-6 and f["odo_end_to_end_err_m"] < 1e-6  # placeholders (0) would not give 0
    assert "Truth heading unknown at" in (tmp_path / "some" / "report.md").read_text()
    with caplog.at_level(logging.WARNING):
        comp = _compare(g.truth_poses(t, xyt, np.zeros(len(t), bool)), est, tmp_path / "none", align="first")
    assert "odo_ate_rmse_m" not in comp.figures
    msgs = [r.getMessage() for r in caplog.records]
    assert len(msgs) == 1 and msgs[0].startswith("odo: align first needs a known truth heading"), msgs


def test_final_drift_on_a_gps_truth_does_not_hang_on_one_course_heading():
    """A drive whose GPS course is 15 deg off for the first second of motion (a car pulling out,
    metre-level fixes) and an estimate that is the true path exactly: its final drift is 0 (the
    start aligned on the positions of the path's first tenth), not the 15 deg x path chord one
    heading would make of it; with every heading known (a survey truth) the first pose is used."""
    from impala_eval.metrics import trajectory_metrics

    t_ns = np.arange(0, 60_000_000_000, 250_000_000, dtype=np.int64)
    s = 10.0 * t_ns * 1e-9
    xyt = np.column_stack([s, 20.0 * np.sin(s / 200.0), np.arctan(0.1 * np.cos(s / 200.0))])
    truth = xyt.copy()
    truth[:4, 2] += math.radians(15.0)  # the course as the car moves off
    known = np.ones(len(t_ns), bool)
    known[0] = False  # at rest: unknown
    m = trajectory_metrics(t_ns, xyt, t_ns, truth, truth_heading_known=known)
    assert m.drift_pct == pytest.approx(0.0, abs=1e-9)
    # the same headings all declared known (no GPS): the first known pose's heading is trusted,
    # 15 deg off over ~600 m: the end is 2 sin(7.5 deg) x its distance from the start away
    survey = trajectory_metrics(t_ns, xyt, t_ns, truth, truth_heading_known=np.ones(len(t_ns), bool))
    chord = float(np.hypot(*(xyt[-1, :2] - xyt[0, :2])))
    travelled = float(np.sum(np.hypot(*np.diff(xyt[:, :2], axis=0).T)))
    assert survey.drift_pct == pytest.approx(100 * 2 * math.sin(math.radians(7.5)) * chord / travelled, rel=1e-6)
