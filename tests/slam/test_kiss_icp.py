"""slam.KissIcp after radar.PeakExtractor on beams built from a known scene with known motion;
the error when kiss-icp is not installed."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from impala_flow.testing import run_graph_text
from impala_msgs import RadarBeam
from impala_radar.datasets.common import navtech_config

pytest.importorskip("kiss_icp")

CONFIG = navtech_config("test-navtech", 576, 0.17361, range_offset_m=0.5 * 0.17361, beams_per_turn=400,
                        rotation_hz=4.0)
BEAM_NS = int(1e9 / (CONFIG.rotation_hz * CONFIG.beams_per_turn))
T0_NS = 1_000_000_000
SPEED_MPS, CURVATURE_1PM, ACCEL_MPS2, REST_S = 8.0, 0.03, 4.0, 0.5

GRAPH = """
name: kiss-icp-scene
clock: {mode: replay, speed: max}
components:
  mission: {type: test.SceneBeams, params: {turns: %(turns)d, gap: %(gap)s}}
  points: {type: radar.PeakExtractor, params: {k: 4, snr_db: 15.0, range_min_m: 2.5, range_max_m: 80.0}}
  kissicp: {type: slam.KissIcp, params: {max_range_m: 80.0, voxel_size_m: 1.0, deskew: %(deskew)s}}
  poses: {type: test.CollectingSink}
connections:
  - mission.out -> points.beams
  - points.detections -> kissicp.detections
  - kissicp.pose -> poses.x
"""


def truth_pose(t_ns: np.ndarray, rest_s: float = REST_S) -> np.ndarray:
    """(x, y, theta) of the vehicle at ``t_ns``: at rest at the origin until ``rest_s`` after T0_NS,
    then accelerating to SPEED_MPS along a circle of curvature CURVATURE_1PM (integrated finely)."""
    ts = np.arange(0.0, 10.0, 1e-4)
    v = np.clip(ACCEL_MPS2 * (ts - rest_s), 0.0, SPEED_MPS)
    s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * 1e-4)])  # distance along the path
    th = CURVATURE_1PM * s
    t = (np.asarray(t_ns, np.int64) - T0_NS) * 1e-9
    d, th_t = np.interp(t, ts, s), np.interp(t, ts, th)
    return np.column_stack([np.sin(th_t) / CURVATURE_1PM, (1.0 - np.cos(th_t)) / CURVATURE_1PM, th_t]) \
        if d.size else np.zeros((0, 3))


def scene(rng: np.random.Generator) -> np.ndarray:
    """Reflectors of a street: two facades (points every 0.7 m), posts and scattered clutter."""
    x = np.arange(-60.0, 120.0, 0.7)
    walls = [np.column_stack([x, np.full_like(x, y0 + 0.05 * x)]) for y0 in (-9.0, 14.0)]
    clutter = rng.uniform([-60, -60], [120, 80], (400, 2))
    return np.concatenate(walls + [clutter])


def scene_beams(turns: int, gap: int = -1, seed: int = 5, rest_s: float = REST_S):
    """Beams of ``turns`` turns seeing ``scene`` from the moving vehicle (each beam at its own
    pose: the turn is distorted by the motion), 30 dB over exponential noise; turn ``gap`` and the
    two after it are missing (a hole in the log)."""
    from impala_flow._component import Output, Param, Source

    class SceneBeams(Source):
        out = Output(RadarBeam)
        turns = Param(int, default=8)
        gap = Param(int, default=-1)

        def generate(self):
            rng = np.random.default_rng(seed)
            pts = scene(rng)
            n_beams, spacing = CONFIG.beams_per_turn, 2 * math.pi / CONFIG.beams_per_turn
            for k in range(self.turns):
                if self.gap >= 0 and self.gap <= k < self.gap + 3:
                    continue
                t_ns = T0_NS + (k * n_beams + np.arange(n_beams)) * BEAM_NS
                pose = truth_pose(t_ns, rest_s)
                az = np.arange(n_beams) * spacing
                power = rng.exponential(1.0, (n_beams, CONFIG.n_bins))
                c, s = np.cos(pose[:, 2])[:, None], np.sin(pose[:, 2])[:, None]
                dx, dy = pts[None, :, 0] - pose[:, 0, None], pts[None, :, 1] - pose[:, 1, None]
                lx, ly = c * dx + s * dy, -s * dx + c * dy  # (beams, reflectors) in the vehicle frame
                seen = np.abs(np.angle(np.exp(1j * (np.arctan2(ly, lx) - az[:, None])))) < 0.5 * spacing
                b, j = np.nonzero(seen)
                rng_bin = np.rint(CONFIG.bin_of_range(np.hypot(lx, ly)[b, j])).astype(int)
                ok = (rng_bin >= 0) & (rng_bin < CONFIG.n_bins)
                np.add.at(power, (b[ok], rng_bin[ok]), 1000.0)
                for i in range(n_beams):
                    yield int(t_ns[i]), "out", RadarBeam(float(az[i]), k, i, power[i].astype(np.float32),
                                                         np.zeros(0, np.float32), CONFIG)

    return SceneBeams


def run(turns: int, deskew: bool = True, gap: int = -1, rest_s: float = REST_S):
    from impala_flow.testing import CollectingSink

    _, net = run_graph_text(GRAPH % {"turns": turns, "deskew": str(deskew).lower(), "gap": gap},
                            scene_beams(turns, gap, rest_s=rest_s), CollectingSink)
    sink = net.components["poses"]
    t = np.array(sink.times(), np.int64)
    est = np.array([[p.x_m, p.y_m, p.theta_rad] for p in sink.values()])
    assert all(p.frame == "odom" for p in sink.values())
    return t, est, net.components["kissicp"]


def errors(t: np.ndarray, est: np.ndarray, rest_s: float = REST_S) -> tuple[float, float]:
    """Largest position (m) and heading (deg) error against the truth, both relative to the first turn."""
    truth = truth_pose(t, rest_s)
    c, s = math.cos(truth[0, 2]), math.sin(truth[0, 2])
    rot = np.array([[c, -s], [s, c]])
    expect = (rot.T @ (truth[:, :2] - truth[0, :2]).T).T
    return (float(np.max(np.hypot(*(est[:, :2] - expect).T))),
            float(np.degrees(np.max(np.abs(est[:, 2] - (truth[:, 2] - truth[0, 2]))))))


def travelled_m(t: np.ndarray, rest_s: float = REST_S) -> float:
    return float(truth_pose(t[-1:], rest_s)[0, 2] / CURVATURE_1PM)


def test_kiss_icp_recovers_a_known_arc_and_deskew_matters():
    t, est, comp = run(16)
    assert len(t) == 16 and comp.skipped_turns == 0
    # each pose stamped at its turn's last point: the last beam, or one of the last few (a beam
    # of this sparse scene may see no reflector)
    end = T0_NS + np.arange(16) * 400 * BEAM_NS + 399 * BEAM_NS
    assert np.all((t <= end) & (t >= end - 8 * BEAM_NS)) and np.all(t % BEAM_NS == 0)
    pos_err, rot_err = errors(t, est)
    assert travelled_m(t) > 19.0  # 20 m along an arc turning 35 deg, 2 m and 3.4 deg per turn at the end
    assert pos_err < 0.01 * travelled_m(t) and rot_err < 0.5
    # the same beams without deskew: each turn smeared by the motion, and the error grows
    pos_raw, rot_raw = errors(*run(16, deskew=False)[:2])
    assert pos_raw > 2 * pos_err


def test_moving_from_the_first_turn():
    """The first two turns enter the map before any motion is known (each smeared by 2 m at
    8 m/s); they are deskewed again once it is, so the third turn meets an undistorted map."""
    t, est, _ = run(16, rest_s=-10.0)
    pos_err, rot_err = errors(t, est, -10.0)
    assert travelled_m(t, -10.0) > 30.0
    assert pos_err < 0.005 * travelled_m(t, -10.0) and rot_err < 0.3


def test_a_hole_in_the_log_is_bridged_by_the_time_since_the_last_turn():
    t, est, comp = run(16, gap=11)
    assert len(t) == 13  # turns 11, 12, 13 missing: 0.75 s without beams at 8 m/s
    pos_err, rot_err = errors(t, est)
    assert pos_err < 0.01 * travelled_m(t) and rot_err < 0.5


def test_without_kiss_icp_one_line_names_the_component_and_the_extra(monkeypatch):
    for name in [m for m in sys.modules if m == "kiss_icp" or m.startswith("kiss_icp.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "kiss_icp", None)  # import kiss_icp now raises ImportError
    from impala_flow import ComponentError

    with pytest.raises(ComponentError) as ei:
        run(2)
    msg = str(ei.value)
    assert "\n" not in msg and "kissicp" in msg and "slam.KissIcp" in msg
    assert "pip install 'impala-flow[peers]'" in msg


def test_the_same_beams_give_bit_identical_poses():
    a, b = run(6, rest_s=-10.0), run(6, rest_s=-10.0)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


def test_graph_on_the_oxford_sample(tmp_path):
    """graphs/kiss_icp_navtech.yaml as a user runs it, on the real Oxford scans against their
    ground truth (the dataset's radar odometry, centimetre-level): the path within 1 %."""
    import json
    from pathlib import Path

    from impala_flow.cli import main

    from ..datasets import oxford_sample_or_skip

    folder = oxford_sample_or_skip()
    mission, out = tmp_path / "oxford.mcap", tmp_path / "out"
    assert main(["import", "oxford", str(folder), "-o", str(mission), "--no-progress"]) == 0
    graph = Path(__file__).resolve().parents[2] / "graphs" / "kiss_icp_navtech.yaml"
    assert main(["run", str(graph), "--var", f"mission={mission}", "--var", f"out={out}", "--no-progress"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["n_poses"] >= 10 and (out / "kiss_icp_navtech.mcap").is_file()
    assert m["ate_rmse_m"] < 0.01 * m["path_length_m"]
    assert m["pair_trans_err_mean_m"] < 0.1 and m["pair_rot_err_mean_deg"] < 0.5
