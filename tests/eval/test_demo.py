"""`impala-flow demo`: the README's first command, shortened, end to end in a subprocess."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from mcap.reader import make_reader

from impala_flow.io import MissionReader


def test_demo_simulates_replays_and_reports(tmp_path):
    out = tmp_path / "demo"
    r = subprocess.run([sys.executable, "-m", "impala_flow", "demo", "--duration", "20", "--out", str(out),
                        "--no-progress"], capture_output=True, text=True, timeout=600, check=False)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "ATE RMSE" in r.stdout and f"report: {out / 'report'}/" in r.stdout
    with open(out / "mission.mcap", "rb") as f:  # the mission, read by the mcap library itself
        topics = [ch.topic for _, ch, _ in make_reader(f).iter_messages()]
    assert topics.count("radar/beams") == 20 * 360  # 1 turn/s, 360 beams per turn (RADAR.md)
    assert {"odometer/speed", "gyro/yaw_rate", "gps/pose"} <= set(topics)
    with MissionReader(out / "mission.mcap") as rd:
        gps = np.array([[m.t_ns, m.data.x_m, m.data.y_m] for m in rd.messages(["gps/pose"])])
    with MissionReader(out / "report" / "rslam.mcap") as rd:
        est_t = np.array([m.t_ns for m in rd.messages(["slam/pose"])], dtype=float)
    est_t = est_t[(est_t >= gps[0, 0]) & (est_t <= gps[-1, 0])]  # only where the truth is known
    # the truth path over the estimate's span, from the recorded GPS at the estimate times
    xy = np.column_stack([np.interp(est_t, gps[:, 0], gps[:, i]) for i in (1, 2)])
    truth_len = float(np.sum(np.hypot(*np.diff(xy, axis=0).T)))
    metrics = json.loads((out / "report" / "metrics.json").read_text())
    assert metrics["n_poses"] == len(est_t)
    assert metrics["path_length_m"] == pytest.approx(truth_len, rel=0.02)
    for key in ("ate_rmse_m", "drift_pct", "baseline_ate_rmse_m"):
        assert math.isfinite(metrics[key])
    # against the dead reckoning of the same run (same odometer and gyro): over 20 s (23 m) its
    # scale error and gyro bias already show (measured 0.13 m, 0.8 deg RMS); R-SLAM's map
    # matching holds the pose (0.03 m, 0.1 deg)
    assert metrics["ate_rmse_m"] < 0.5 * metrics["baseline_ate_rmse_m"]
    assert metrics["heading_rmse_deg"] < 0.5 * metrics["baseline_heading_rmse_deg"]
    assert metrics["drift_pct"] < 0.5 * metrics["baseline_drift_pct"]
    for png in ("error_vs_distance.png", "trajectory_map.png", "map.png"):
        assert (out / "report" / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_demo_chain_is_the_documented_rslam_graph():
    """The demo ships its own copy (a pip install has no graphs/ folder): keep them one."""
    from pathlib import Path

    from impala_eval.demo import GRAPHS

    repo = Path(__file__).resolve().parents[2]
    assert GRAPHS["rslam"].read_text() == (repo / "graphs" / "rslam.yaml").read_text()
