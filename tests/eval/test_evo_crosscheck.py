"""The ATE of impala_eval against evo's ``evo_ape`` (GPL-3.0: command line only, never imported)."""

import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from impala_eval.evaluator.component import TrajectoryEvaluator
from impala_eval.metrics import trajectory_metrics

EVO_APE = shutil.which("evo_ape") or shutil.which("evo_ape", path=str(Path(sys.executable).parent))


def _tum(path, t_ns, xyt):
    with open(path, "w") as f:
        for t, (x, y, th) in zip(t_ns.tolist(), xyt.tolist(), strict=True):
            f.write(f"{t // 1_000_000_000}.{t % 1_000_000_000:09d} {x:.9f} {y:.9f} 0 0 0 "
                    f"{np.sin(th / 2):.12f} {np.cos(th / 2):.12f}\n")


@pytest.mark.skipif(EVO_APE is None, reason="evo_ape not on PATH (pip install evo)")
def test_ate_matches_evo_ape(tmp_path):
    rng = np.random.default_rng(5)
    n = 300
    t = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 100_000_000
    s = np.arange(n) * 0.2
    truth = np.column_stack([20 * np.cos(s / 15), 10 * np.sin(s / 9), s / 15])
    est = truth.copy()
    c, sn = np.cos(0.4), np.sin(0.4)
    est[:, :2] = truth[:, :2] @ np.array([[c, sn], [-sn, c]]) + (3.0, -7.0) + rng.normal(0, 0.3, (n, 2))
    est[:, 2] += 0.4
    stats = _evo_stats(tmp_path, t, truth, t, est)
    m = trajectory_metrics(t, est, t, truth, "rigid")
    assert m.ate_rmse_m == pytest.approx(stats["rmse"], rel=1e-6)
    assert m.ate_mean_m == pytest.approx(stats["mean"], rel=1e-6)
    assert m.ate_max_m == pytest.approx(stats["max"], rel=1e-6)


def _evo_stats(tmp_path, t_truth, truth, t_est, est):
    _tum(tmp_path / "truth.tum", t_truth, truth)
    _tum(tmp_path / "est.tum", t_est, est)
    out = tmp_path / "ape.zip"
    subprocess.run([EVO_APE, "tum", str(tmp_path / "truth.tum"), str(tmp_path / "est.tum"), "--align",
                    "--save_results", str(out), "--no_warnings"], check=True, capture_output=True, timeout=120)
    with zipfile.ZipFile(out) as z:
        return json.loads(z.read("stats.json"))


@pytest.mark.skipif(EVO_APE is None, reason="evo_ape not on PATH (pip install evo)")
@pytest.mark.parametrize("kind", ["clean, heading unknown at rest", "noisy 20 Hz GPS, repeats and a hole"])
def test_ate_of_a_4hz_estimate_against_a_20hz_gps_truth_matches_evo_ape(tmp_path, kind):
    """The evaluator and the comparison run as a graph runs them, on Pose2D streams (truth
    headings unknown at rest, the estimate at 4 Hz on every 5th GPS time); evo_ape --align
    (SE(3) Umeyama on the positions, z = 0) on the same poses, the GPS file holding each
    fix once (evo matches by stamp: the estimate's poses in the GPS hole find no truth)."""
    from impala_eval.comparison.component import TrajectoryComparison
    from impala_flow.msgs import Pose2D
    from impala_flow.testing import ScriptedSource, run_components

    from . import gps_drive as g

    d = g.drive()
    if kind.startswith("clean"):
        t, xyt, known = g.gps(d, noise_m=0.0, white_m=0.0, hole_s=None, repeat=False)
    else:
        t, xyt, known = g.gps(d, seed=11)
    te, xe = g.estimate(d)
    assert not known.all()
    script = [(tt, "truth", p) for tt, p in g.truth_poses(t, xyt, known)]
    script += [(int(tt), "est", Pose2D(*p)) for tt, p in zip(te, xe.tolist(), strict=True)]
    script.sort(key=lambda s: s[0])
    ev = TrajectoryEvaluator("eval", align="rigid")
    comp = TrajectoryComparison("compare", estimates=["odo"], poses=["odo"], align="rigid",
                                report=str(tmp_path / "compare"))
    run_components(ScriptedSource("s", script), ev, comp, connections=[
        "s.truth -> eval.truth", "s.est -> eval.estimate", "s.truth -> compare.truth", "s.est -> compare.odo"])
    once = np.unique(t, return_index=True)[1]
    stats = _evo_stats(tmp_path, t[once], xyt[once], te, xe)
    assert ev.figures["ate_rmse_m"] == pytest.approx(stats["rmse"], rel=1e-6)
    assert ev.figures["ate_mean_m"] == pytest.approx(stats["mean"], rel=1e-6)
    assert ev.figures["ate_max_m"] == pytest.approx(stats["max"], rel=1e-6)
    assert comp.figures["odo_ate_rmse_m"] == pytest.approx(stats["rmse"], rel=1e-6)
    assert (tmp_path / "compare" / "trajectories.png").stat().st_size > 20_000
