"""R-SLAM on the real Oxford Radar RobotCar scans, through the command line a user runs:
``impala-flow import oxford`` then ``impala-flow run graphs/oxford.yaml`` (issue 9 items 2-3).

The estimate is read back from the graph's recording with the bare mcap library and the
Foxglove PoseInFrame schema (its ``/foxglove/slam/pose`` mirror), never with impala-flow's
codec; the truth is ``gt/radar_odometry.csv`` parsed here with the csv module (Oxford's
frame: x forward, y right, yaw clockwise; each row the pose of the source scan in the
destination scan's frame, stamped at the middle of the source scan).
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from mcap.reader import make_reader

from impala_flow.cli import main

from ..datasets import oxford_sample_or_skip

cv2.setNumThreads(1)
GRAPH = Path(__file__).resolve().parents[2] / "graphs" / "oxford.yaml"


def _truth_rows(folder: Path) -> dict[int, tuple[int, float, float, float]]:
    """source_timestamp (ns) -> (destination_timestamp ns, x, y, yaw) in the project's frame
    (x forward, y left, yaw counter-clockwise)."""
    out = {}
    with open(folder / "gt" / "radar_odometry.csv", newline="") as f:
        for row in csv.DictReader(f):
            out[int(row["source_timestamp"]) * 1000] = (int(row["destination_timestamp"]) * 1000, float(row["x"]),
                                                        -float(row["y"]), -float(row["yaw"]))
    return out


def _recorded_poses(path: Path) -> dict[int, tuple[float, float, float]]:
    poses = {}
    with open(path, "rb") as f:
        for _, _, message in make_reader(f).iter_messages(topics=["/foxglove/slam/pose"]):
            p = PoseInFrame()
            p.ParseFromString(message.data)
            q = p.pose.orientation
            poses[message.log_time] = (p.pose.position.x, p.pose.position.y,
                                       2.0 * math.atan2(q.z, q.w))  # a yaw-only quaternion
    return poses


@pytest.fixture(scope="module")
def oxford_run(tmp_path_factory):
    folder = oxford_sample_or_skip()
    tmp = tmp_path_factory.mktemp("oxford")
    mission = tmp / "oxford-sample.mcap"
    assert main(["import", "oxford", str(folder), "-o", str(mission), "--no-progress"]) == 0
    out = tmp / "out"
    assert main(["run", str(GRAPH), "--var", f"mission={mission}", "--var", f"out={out}", "--no-progress"]) == 0
    return folder, out


def test_the_graph_registers_every_consecutive_pair_within_the_required_error(oxford_run):
    folder, out = oxford_run
    truth = _truth_rows(folder)
    est = _recorded_poses(out / "oxford.mcap")
    assert len(est) == 11  # one pose per scan, stamped at the middle of the scan like the truth

    def at(t_ns):  # the estimate stamped at the truth's time (the CSV rounds it to the microsecond)
        near = [t for t in est if abs(t - t_ns) <= 1000]
        return est[near[0]] if near else None

    trans, rot = [], []
    for t, (t_dst, x, y, yaw) in truth.items():
        if at(t) is None or at(t_dst) is None:
            continue
        (x0, y0, th0), (x1, y1, th1) = at(t_dst), at(t)
        c, s = math.cos(th0), math.sin(th0)
        dx, dy = x1 - x0, y1 - y0
        rel = (c * dx + s * dy, -s * dx + c * dy, th1 - th0)
        trans.append(math.hypot(rel[0] - x, rel[1] - y))
        rot.append(abs(math.degrees(math.remainder(rel[2] - yaw, 2 * math.pi))))
    assert len(trans) == 10  # 11 scans, 10 consecutive pairs
    print(f"\nOxford pairs: mean {100 * np.mean(trans):.1f} cm / {np.mean(rot):.3f} deg, "
          f"max {100 * np.max(trans):.1f} cm / {np.max(rot):.3f} deg")
    # required by the issue: 10 cm and 0.2 deg (Cen & Newman report 5.2 cm and 0.09 deg)
    assert np.mean(trans) <= 0.10 and np.mean(rot) <= 0.2
    assert np.max(trans) < 0.2
    # the evaluator's report says the same, pair by pair (it interpolates the truth at the exact
    # estimate times, the CSV rounds them to the microsecond: 10 m/s x 0.5 us = 5 um)
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["n_pairs"] == 10
    assert metrics["pair_trans_err_mean_m"] == pytest.approx(np.mean(trans), abs=2e-5)
    assert metrics["pair_rot_err_mean_deg"] == pytest.approx(np.mean(rot), abs=1e-4)
    assert sorted(p["trans_err_m"] for p in metrics["pairs"]) == pytest.approx(sorted(trans), abs=2e-5)


def test_registration_beats_the_constant_velocity_prediction(oxford_run):
    metrics = json.loads((oxford_run[1] / "metrics.json").read_text())
    # the motion model alone (the baseline) is the prediction R-SLAM starts from
    assert metrics["pair_trans_err_mean_m"] < 0.5 * metrics["baseline_pair_trans_err_mean_m"]
    assert metrics["ate_rmse_m"] < metrics["baseline_ate_rmse_m"]


def test_the_report_draws_the_pairs(oxford_run):
    out = oxford_run[1]
    for name in ("pair_errors.png", "error_vs_distance.png", "trajectory_map.png", "map.png"):
        img = cv2.imread(str(out / name))
        assert img is not None and img.shape[0] > 300 and img.std() > 5.0, name


def test_fmt_registration_beside_rslam_on_the_same_pairs(oxford_run):
    """slam.FmtRegistration in the same graph (issue 14): its transforms, read back with the
    project's reader, against the CSV's pairs; R-SLAM's per-pair error printed beside."""
    from impala_flow.io._reader import MissionReader

    folder, out = oxford_run
    truth = _truth_rows(folder)
    trans, rot = [], []
    with MissionReader(out / "oxford.mcap") as reader:
        transforms = [m.data for m in reader.messages(["fmt/transform"])]
    for c in transforms:
        if c.kind != "registration":
            continue
        rows = [(t, r) for t, r in truth.items() if abs(t - c.to_t_ns) <= 1000 and abs(r[0] - c.from_t_ns) <= 1000]
        if not rows:
            continue
        _, (_, x, y, yaw) = rows[0]
        trans.append(math.hypot(c.x_m - x, c.y_m - y))
        rot.append(abs(math.degrees(math.remainder(c.theta_rad - yaw, 2 * math.pi))))
    assert len(trans) == 10
    rslam = json.loads((out / "metrics.json").read_text())
    print(f"\nOxford pairs, FMT: mean {100 * np.mean(trans):.1f} cm / {np.mean(rot):.3f} deg; R-SLAM: "
          f"{100 * rslam['pair_trans_err_mean_m']:.1f} cm / {rslam['pair_rot_err_mean_deg']:.3f} deg")
    assert np.mean(trans) <= 0.10 and np.mean(rot) <= 0.25
    assert np.max(trans) < 0.2
