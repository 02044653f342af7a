"""The ATE of impala_eval against evo's ``evo_ape`` (GPL-3.0: command line only, never imported)."""

import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from impala_eval import trajectory_metrics

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
    _tum(tmp_path / "truth.tum", t, truth)
    _tum(tmp_path / "est.tum", t, est)
    out = tmp_path / "ape.zip"
    subprocess.run([EVO_APE, "tum", str(tmp_path / "truth.tum"), str(tmp_path / "est.tum"), "--align",
                    "--save_results", str(out), "--no_warnings"], check=True, capture_output=True, timeout=120)
    with zipfile.ZipFile(out) as z:
        stats = json.loads(z.read("stats.json"))
    m = trajectory_metrics(t, est, t, truth, "rigid")
    assert m.ate_rmse_m == pytest.approx(stats["rmse"], rel=1e-6)
    assert m.ate_mean_m == pytest.approx(stats["mean"], rel=1e-6)
    assert m.ate_max_m == pytest.approx(stats["max"], rel=1e-6)
