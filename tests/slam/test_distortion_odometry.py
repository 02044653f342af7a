"""slam.DistortionOdometry (issue 12): radar-only odometry from the scans' distortion.

Two sources of beams, both independent of the component: a small synthetic radar written
here (point scatterers, Gaussian beam and range peak, each ramp shifted by the echo's
Doppler; exact trajectories for the failure modes: stationary, pure rotation, sudden stop,
open field, either rotation sense, any beams per turn), and the project's simulator on the
semi-urban scenario run through graphs/odometry.yaml as a user runs it. The truth's speed
and yaw rate are computed here from the trajectories (numpy), never taken from the code.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from impala_flow.io import MissionReader
from impala_flow.testing import CollectingSink, ScriptedSource, run_components
from impala_msgs import RadarBeam, RadarConfig
from impala_slam.odometry.component import DistortionOdometry
from impala_slam.odometry.distortion import doppler_beta_s

ROOT = Path(__file__).resolve().parents[2]
C = 299_792_458.0


def _config(beams: int) -> RadarConfig:
    # IMPALA's numbers (seed 1 Fig. 2), written out: 24 GHz, 200 MHz, Fm 360 Hz, 1 turn/s
    return RadarConfig("synthetic", 24.0e9, 200.0e6, 360.0, 360.0, 288, math.radians(4.0), 1.0, beams, 3.0, 100.0)


def _trajectory(v_of_t, w_of_t, seconds: float, dt: float = 1e-3):
    """Pose (x, y, theta) at any time by integrating v(t), w(t) on a fine grid (midpoint)."""
    t = np.arange(0.0, seconds + dt, dt)
    tm = t[:-1] + 0.5 * dt
    th = np.concatenate([[0.0], np.cumsum(w_of_t(tm) * dt)])
    thm = 0.5 * (th[1:] + th[:-1])
    x = np.concatenate([[0.0], np.cumsum(v_of_t(tm) * np.cos(thm) * dt)])
    y = np.concatenate([[0.0], np.cumsum(v_of_t(tm) * np.sin(thm) * dt)])
    return lambda q: np.column_stack([np.interp(q, t, x), np.interp(q, t, y), np.interp(q, t, th)])


def _world(rng, n: int = 260, half_m: float = 120.0, empty_after_x_m: float | None = None):
    pts = rng.uniform(-half_m, half_m, (n, 2))
    pts = pts[np.hypot(*pts.T) > 4.0]
    if empty_after_x_m is not None:
        pts = pts[pts[:, 0] < empty_after_x_m - 80.0]  # nothing within radar range after that x
    return pts, rng.uniform(1.0, 4.0, len(pts))


def _beams(pose_of_t, v_of_t, world, seconds: float, beams: int, clockwise: bool, rng, start_az: float = 0.4):
    """RadarBeam samples of a rotating triangular-FMCW radar moving along ``pose_of_t``."""
    cfg = _config(beams)
    pts, amp = world
    k_range = 4.0 * cfg.bandwidth_hz * cfg.modulation_hz / C  # Hz per m
    bins = np.arange(cfg.n_bins, dtype=float)
    sb = cfg.beam_width_rad / 2.3548
    out = []
    n_turns = int(seconds * cfg.rotation_hz)
    for turn in range(n_turns):
        j = np.arange(beams)
        t = (turn + (j + 0.5) / beams) / cfg.rotation_hz
        az = start_az + (-1.0 if clockwise else 1.0) * 2.0 * np.pi * (j + 0.5) / beams
        pose = pose_of_t(t)
        v = v_of_t(t)
        d = pts[None, :, :] - pose[:, None, :2]
        r = np.hypot(d[..., 0], d[..., 1])
        bearing = np.arctan2(d[..., 1], d[..., 0]) - pose[:, 2:3]
        off = np.angle(np.exp(1j * (bearing - az[:, None])))
        g = amp[None, :] * np.exp(-0.5 * (off / sb) ** 2) * (r < 95.0)
        vr = -v[:, None] * np.cos(bearing)  # range rate of a static point (radar at the rotation centre)
        shift = 2.0 * vr * cfg.f0_hz / C / k_range  # Doppler in metres of range
        spectra = []
        for sign in (1.0, -1.0):
            kb = (r + sign * shift) / cfg.range_per_bin_m
            live = g > 1e-4
            spec = rng.exponential(1.0, (beams, cfg.n_bins))
            bi, pi = np.nonzero(live)
            np.add.at(spec, bi, (1e3 * g[bi, pi])[:, None] * np.exp(-0.5 * ((bins[None, :] - kb[bi, pi][:, None])
                                                                             / 1.4) ** 2))
            spectra.append(spec.astype(np.float32))
        for i in range(beams):
            out.append((int(round(t[i] * 1e9)), "beams",
                        RadarBeam(float(az[i]), turn, i, spectra[0][i], spectra[1][i], cfg)))
    return out


def _run(samples, **params):
    twist, pose, degraded = CollectingSink("twist"), CollectingSink("pose"), CollectingSink("degraded")
    odo = DistortionOdometry("odo", map_cell_m=0.0, **params)
    run_components(ScriptedSource("src", samples=samples, ports=["beams"]), odo, twist, pose, degraded,
                   connections=["src.beams -> odo.beams", "odo.twist -> twist.x", "odo.pose -> pose.x",
                                "odo.degraded -> degraded.x"])
    t = np.array(twist.times(), float) * 1e-9
    vw = np.array([[s.speed_mps, s.yaw_rate_radps] for s in twist.values()]).reshape(-1, 2)
    xyt = np.array([[p.x_m, p.y_m, p.theta_rad] for p in pose.values()]).reshape(-1, 3)
    cov = [s.cov for s in twist.values()]
    return t, vw, xyt, cov, [d.value for d in degraded.values()], odo.summary()


def _truth_twist(pose_of_t, t, h=0.5):
    a, b = pose_of_t(t - h), pose_of_t(t + h)
    d = b - a
    mid = a[:, 2] + 0.5 * d[:, 2]
    return (np.cos(mid) * d[:, 0] + np.sin(mid) * d[:, 1]) / (2 * h), d[:, 2] / (2 * h)


@pytest.mark.parametrize("clockwise,beams", [(False, 360), (True, 360), (True, 400), (False, 256)])
def test_constant_turn_recovered_either_sense_any_beams(clockwise, beams):
    rng = np.random.default_rng(11)
    v0, w0 = 7.0, math.radians(6.0)
    pose = _trajectory(lambda t: np.full_like(t, v0), lambda t: np.full_like(t, w0), 9.0)
    t, vw, xyt, _, degraded, summary = _run(_beams(pose, lambda t: np.full_like(t, v0), _world(rng), 9.0, beams,
                                                  clockwise, rng))
    assert len(t) == 8 and not any(degraded)
    np.testing.assert_allclose(vw[:, 0], v0, atol=0.1)
    np.testing.assert_allclose(np.degrees(vw[:, 1]), 6.0, atol=0.3)
    # the pose is the integral of the rates: compare with the truth's displacement between outputs
    truth = pose(t)
    rel = np.hypot(*(xyt[-1, :2] - xyt[0, :2]).T) - np.hypot(*(truth[-1, :2] - truth[0, :2]).T)
    assert abs(rel) < 0.1 * 7
    assert summary["partial_turns"] == 0


def test_doppler_compensation_removes_the_range_shift_bias():
    """Beams carry the Doppler shift of each ramp (2 v_r f0 / c); without the compensation the
    two ramps' echoes disagree by 2 beta v cos(phi): compensated, the speed error is smaller."""
    rng = np.random.default_rng(5)
    v0 = 9.0
    pose = _trajectory(lambda t: np.full_like(t, v0), lambda t: np.zeros_like(t), 7.0)
    samples = _beams(pose, lambda t: np.full_like(t, v0), _world(rng), 7.0, 360, False, rng)
    # the shift model: beta = f0 / (2 dF Fm) s for a triangular radar (seed 1 eq. 2)
    assert doppler_beta_s(_config(360)) == pytest.approx(24e9 / (2 * 200e6 * 360))
    on = _run(samples)[1][:, 0]
    off = _run(samples, doppler=False)[1][:, 0]
    assert np.mean(np.abs(on - v0)) < 0.06
    assert np.mean(np.abs(on - v0)) <= np.mean(np.abs(off - v0)) + 0.02


def test_stationary_and_pure_rotation():
    rng = np.random.default_rng(3)
    world = _world(rng)
    pose = _trajectory(lambda t: np.zeros_like(t), lambda t: np.zeros_like(t), 6.0)
    _, vw, xyt, _, degraded, _ = _run(_beams(pose, lambda t: np.zeros_like(t), world, 6.0, 360, False, rng))
    assert np.all(np.abs(vw[:, 0]) < 0.05) and np.all(np.abs(np.degrees(vw[:, 1])) < 0.2)
    assert np.all(np.hypot(*xyt[:, :2].T) < 0.2) and not any(degraded)
    w0 = math.radians(15.0)
    pose = _trajectory(lambda t: np.zeros_like(t), lambda t: np.full_like(t, w0), 6.0)
    _, vw, _, _, _, _ = _run(_beams(pose, lambda t: np.zeros_like(t), world, 6.0, 360, True, rng))
    assert np.all(np.abs(vw[:, 0]) < 0.05)
    np.testing.assert_allclose(np.degrees(vw[:, 1]), 15.0, atol=0.3)


def test_sudden_stop_followed_without_jump_or_nan():
    """8 m/s, then braking at 4 m/s^2 (more than the filter's model expects) to a stop."""
    rng = np.random.default_rng(8)
    v_of_t = lambda t: np.clip(8.0 - 4.0 * np.maximum(t - 4.0, 0.0), 0.0, None)  # noqa: E731
    pose = _trajectory(v_of_t, lambda t: np.zeros_like(t), 11.0)
    t, vw, xyt, cov, degraded, summary = _run(_beams(pose, v_of_t, _world(rng), 11.0, 360, False, rng))
    assert np.all(np.isfinite(vw)) and np.all(np.isfinite(xyt))
    v_true, _ = _truth_twist(pose, t)
    assert np.max(np.abs(vw[:, 0] - v_true)) < 1.0  # the two-turn mean through the braking
    assert np.all(np.abs(vw[-3:, 0]) < 0.1)  # stopped
    steps = np.hypot(*np.diff(xyt[:, :2], axis=0).T)
    assert np.max(steps) < 9.0  # no jump: at most one turn at the top speed (+ margin)
    truth = pose(t)
    assert abs(np.hypot(*(xyt[-1, :2] - xyt[0, :2])) - np.hypot(*(truth[-1, :2] - truth[0, :2]))) < 1.0


def test_open_field_degrades_and_the_covariance_grows():
    """The world ends: turns with no echo give no measurement; the filter predicts, its
    covariance grows, the output says so, and no NaN or jump appears."""
    rng = np.random.default_rng(4)
    v0 = 6.0
    pose = _trajectory(lambda t: np.full_like(t, v0), lambda t: np.zeros_like(t), 14.0)
    world = _world(rng, n=400, empty_after_x_m=40.0)
    t, vw, xyt, cov, degraded, summary = _run(_beams(pose, lambda t: np.full_like(t, v0), world, 14.0, 360, False,
                                                    rng))
    assert summary["degraded_turns"] >= 3 and sum(degraded) == summary["degraded_turns"]
    d = np.array(degraded, bool)
    var_v = np.array([c[0, 0] for c in cov])
    assert np.all(np.diff(var_v[d]) > 0)  # grows turn after turn without measurements
    assert var_v[d][-1] > 10 * var_v[~d][0]
    assert np.all(np.isfinite(vw)) and np.all(np.isfinite(xyt))
    assert np.max(np.hypot(*np.diff(xyt[:, :2], axis=0).T)) < 8.0


def _stamped_late(samples, delay_s: dict[int, float]):
    """The beams of turn k stamped ``delay_s[k]`` late, the way a RADIATE log reads after its
    logger stalls: one time per turn (its first beam's), the turn's beams spread evenly up to the
    next turn's time (as the RADIATE import does)."""
    turns: dict[int, list] = {}
    for t, port, b in samples:
        turns.setdefault(b.turn, []).append((t, port, b))
    keys = sorted(turns)
    stamp = {k: turns[k][0][0] + int(round(delay_s.get(k, 0.0) * 1e9)) for k in keys}
    period = turns[keys[1]][0][0] - turns[keys[0]][0][0]
    out = []
    for i, k in enumerate(keys):
        span = min(period, stamp[keys[i + 1]] - stamp[k]) if i + 1 < len(keys) else period
        n = len(turns[k])
        out += [(stamp[k] + j * span // n, port, b) for j, (_, port, b) in enumerate(turns[k])]
    return out


def test_late_time_stamps_are_not_read_as_a_stop():
    """A logger stalls for 0.8 s then catches up over four turns (RADIATE's radar log does so,
    up to 1.6 s): read literally, the turn after the stall is 1.8 s from the previous one and the
    car would seem to slow to half its speed, then speed up. The speed stays the truth's, the
    poses come at the turns' true times, and the distance is the truth's. A turn really missing
    (same gap, no catching up) is read as such."""
    rng = np.random.default_rng(9)
    v0 = 7.0
    pose = _trajectory(lambda t: np.full_like(t, v0), lambda t: np.full_like(t, math.radians(3.0)), 12.0)
    samples = _beams(pose, lambda t: np.full_like(t, v0), _world(rng), 12.0, 360, True, rng)
    late = _stamped_late(samples, {4: 0.8, 5: 0.6, 6: 0.4, 7: 0.2})
    t, vw, xyt, _, degraded, summary = _run(late)
    assert summary["late_stamps"] == 1 and summary["missing_turns"] == 0 and not any(degraded)
    np.testing.assert_allclose(vw[:, 0], v0, atol=0.1)
    np.testing.assert_allclose(t, np.arange(1.0, 12.0), atol=0.01)  # turn k starts at k s (first beam)
    truth = pose(t)
    assert abs(np.hypot(*(xyt[-1, :2] - xyt[0, :2])) - np.hypot(*(truth[-1, :2] - truth[0, :2]))) < 0.2
    # the same gap with a turn really missing
    t, vw, xyt, _, _, summary = _run([s for s in samples if s[2].turn != 4])
    assert summary["late_stamps"] == 0 and summary["missing_turns"] == 1
    np.testing.assert_allclose(vw[:, 0], v0, atol=0.15)
    truth = pose(t)
    assert abs(np.hypot(*(xyt[-1, :2] - xyt[0, :2])) - np.hypot(*(truth[-1, :2] - truth[0, :2]))) < 0.3


@pytest.fixture(scope="module")
def semi_urban(tmp_path_factory):
    """18 s of the semi-urban scenario (seed 21, not a tuning seed) through graphs/odometry.yaml."""
    tmp = tmp_path_factory.mktemp("odometry")
    mission = tmp / "semi-urban.mcap"
    cli = [sys.executable, "-m", "impala_flow"]
    subprocess.run(cli + ["simulate", "semi-urban", "-o", str(mission), "--duration", "18s", "--seed", "21",
                          "--no-progress"], check=True, capture_output=True)
    out = tmp / "out"
    subprocess.run(cli + ["run", str(ROOT / "graphs" / "odometry.yaml"), "--var", f"mission={mission}",
                          "--var", f"out={out}"], check=True, capture_output=True)
    return mission, out


def test_semi_urban_through_the_graph(semi_urban):
    mission, out = semi_urban
    with MissionReader(mission) as r:
        gps = [(m.t_ns, m.data.x_m, m.data.y_m, m.data.theta_rad) for m in r.messages(["gps/pose"])]
    with MissionReader(out / "odometry.mcap") as r:
        topics = set(r.topics)
        tw = [(m.t_ns, m.data.speed_mps, m.data.yaw_rate_radps) for m in r.messages(["odometry/twist"])]
    assert {"odometry/pose", "odometry/twist", "odometry/degraded", "odometry/map"} <= topics
    g = np.array(gps, float)
    tg = (g[:, 0] - g[0, 0]) * 1e-9
    th = np.unwrap(g[:, 3])
    e = np.array(tw, float)
    te = (e[:, 0] - g[0, 0]) * 1e-9
    keep = (te - 0.5 >= tg[0]) & (te + 0.5 <= tg[-1])
    te, e = te[keep], e[keep]
    # truth: RTK positions 1 s apart around each estimate
    xa, ya = np.interp(te - 0.5, tg, g[:, 1]), np.interp(te - 0.5, tg, g[:, 2])
    xb, yb = np.interp(te + 0.5, tg, g[:, 1]), np.interp(te + 0.5, tg, g[:, 2])
    v_true = np.hypot(xb - xa, yb - ya)
    w_true = np.interp(te + 0.5, tg, th) - np.interp(te - 0.5, tg, th)
    err_v, err_w = e[:, 1] - v_true, np.degrees(e[:, 2] - w_true)
    assert len(err_v) >= 14
    assert abs(np.mean(err_v)) <= 0.1 and np.std(err_v) <= 0.3
    assert abs(np.mean(err_w)) <= 0.3
    import json
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["speed_err_mean_mps"] == pytest.approx(np.mean(err_v), abs=0.03)
    for png in ("twist_errors.png", "trajectory_map.png", "map.png", "error_vs_distance.png"):
        assert (out / png).stat().st_size > 10_000


def test_oxford_pairs_through_the_navtech_graph(tmp_path):
    """Real Navtech scans (Oxford sample, 4 Hz, power only) through graphs/odometry_navtech.yaml:
    the relative motion between consecutive output poses against the dataset's truth (the
    imported truth/pose, interpolated at the outputs' times here), within issue 9's limits
    for scan registration (10 cm, 0.2 deg per pair)."""
    from impala_flow.cli import main

    from ..datasets import oxford_sample_or_skip

    folder = oxford_sample_or_skip()
    mission = tmp_path / "oxford.mcap"
    assert main(["import", "oxford", str(folder), "-o", str(mission), "--no-progress"]) == 0
    out = tmp_path / "out"
    assert main(["run", str(ROOT / "graphs" / "odometry_navtech.yaml"), "--var", f"mission={mission}",
                 "--var", f"out={out}", "--no-progress"]) == 0
    with MissionReader(mission) as r:
        truth = np.array([(m.t_ns, m.data.x_m, m.data.y_m, m.data.theta_rad) for m in r.messages(["truth/pose"])])
    with MissionReader(out / "odometry_navtech.mcap") as r:
        est = np.array([(m.t_ns, m.data.x_m, m.data.y_m, m.data.theta_rad) for m in r.messages(["odometry/pose"])])
    assert len(est) >= 9
    t0 = truth[0, 0]
    tt, te = (truth[:, 0] - t0) * 1e-9, (est[:, 0] - t0) * 1e-9
    inside = (te >= tt[0]) & (te <= tt[-1])
    te, est = te[inside], est[inside]
    g = np.column_stack([np.interp(te, tt, truth[:, 1]), np.interp(te, tt, truth[:, 2]),
                         np.interp(te, tt, np.unwrap(truth[:, 3]))])

    def steps(p):
        c, s = np.cos(p[:-1, 2]), np.sin(p[:-1, 2])
        d = np.diff(p[:, :2], axis=0)
        return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], np.diff(p[:, 2])])

    e = steps(est[:, 1:]) - steps(g)
    trans = np.hypot(e[:, 0], e[:, 1])
    assert len(trans) >= 8
    assert np.mean(trans) <= 0.10 and np.degrees(np.mean(np.abs(e[:, 2]))) <= 0.2


def test_same_mission_same_bytes_at_any_speed(semi_urban):
    """Deterministic offline runs: the recording and the metrics are bit-identical when the
    same mission runs again into the same folder, paced this time."""
    import shutil

    mission, out = semi_urban
    first = {p.name: p.read_bytes() for p in out.iterdir() if p.suffix in (".mcap", ".json")}
    shutil.rmtree(out)
    subprocess.run([sys.executable, "-m", "impala_flow", "run", str(ROOT / "graphs" / "odometry.yaml"), "--var",
                    f"mission={mission}", "--var", f"out={out}", "--no-progress", "--speed", "12"], check=True,
                   capture_output=True)
    second = {p.name: p.read_bytes() for p in out.iterdir() if p.suffix in (".mcap", ".json")}
    assert set(first) == {"odometry.mcap", "metrics.json"} and first == second


@pytest.fixture(scope="module")
def edinburgh(edinburgh_mission, tmp_path_factory):
    """The real RADIATE Edinburgh head (400 turns, GPS; imported once, tests/conftest.py) run through
    graphs/odometry_navtech.yaml as a user does: truth (t, x, y) and estimate (t, x, y, theta)."""
    from impala_flow.cli import main

    mission = edinburgh_mission
    out = tmp_path_factory.mktemp("edinburgh-odometry") / "out"
    assert main(["run", str(ROOT / "graphs" / "odometry_navtech.yaml"), "--var", f"mission={mission}",
                 "--var", f"out={out}", "--no-progress", "--set", "odometry.map_cell_m=0"]) == 0
    with MissionReader(mission) as r:
        truth = np.array([(m.t_ns, m.data.x_m, m.data.y_m) for m in r.messages(["truth/pose"])], float)
    with MissionReader(out / "odometry_navtech.mcap") as r:
        est = np.array([(m.t_ns, m.data.x_m, m.data.y_m, m.data.theta_rad) for m in r.messages(["odometry/pose"])])
    t0 = truth[0, 0]
    truth[:, 0] = (truth[:, 0] - t0) * 1e-9
    est[:, 0] = (est[:, 0] - t0) * 1e-9
    return truth, est


def _gps_speed(truth, window_s=4.0):
    """GPS speed over ``window_s`` (centred), every 0.25 s: (times, m/s)."""
    t = truth[:, 0]

    def at(q):
        return np.column_stack([np.interp(q, t, truth[:, 1]), np.interp(q, t, truth[:, 2])])

    q = np.arange(t[0] + window_s / 2, t[-1] - window_s / 2, 0.25)
    return q, np.hypot(*(at(q + window_s / 2) - at(q - window_s / 2)).T) / window_s


def _gps_rest(truth, speed_mps=0.15, min_s=10.0, margin_s=2.0):
    """Intervals where the GPS moves slower than ``speed_mps``, at least ``min_s`` long, shrunk
    by ``margin_s`` at both ends."""
    q, v = _gps_speed(truth)
    rest = v < speed_mps
    edges = np.flatnonzero(np.diff(np.concatenate([[0], rest.astype(int), [0]])))
    return [(q[a] + margin_s, q[b - 1] - margin_s) for a, b in zip(edges[::2], edges[1::2], strict=True)
            if q[b - 1] - q[a] >= min_s]


def test_edinburgh_standing_still_does_not_move_the_estimate(edinburgh):
    """The car waits about a minute at the start (RADIATE, real scans). Over every interval where
    the GPS is at rest, the estimate stays within the GPS's own scatter there (its largest distance
    from its mean: the receiver's noise at rest) and its heading within 4 azimuth steps (a RADIATE
    image's columns jitter by up to two azimuths from turn to turn, at each end)."""
    truth, est = edinburgh
    rests = _gps_rest(truth)
    assert sum(b - a for a, b in rests) > 25.0  # the minute at the start (less the GPS's creeping and margins)
    for a, b in rests:
        g = truth[(truth[:, 0] >= a) & (truth[:, 0] <= b), 1:3]
        scatter_m = float(np.max(np.hypot(*(g - g.mean(axis=0)).T)))
        e = est[(est[:, 0] >= a) & (est[:, 0] <= b)]
        assert len(e) >= 30
        moved_m = float(np.max(np.hypot(*(e[:, 1:3] - e[0, 1:3]).T)))
        assert moved_m <= scatter_m, (a, b, moved_m, scatter_m)
        turned = np.abs(np.unwrap(e[:, 3]) - e[0, 3])
        assert np.degrees(np.max(turned)) <= 4 * 0.9, (a, b)


def test_edinburgh_drive_against_gps(edinburgh):
    """The drive after the wait (~300 m from the GPS's 2 m/s on, up to ~11 m/s): absolute trajectory error after a rigid
    fit of positions (Kabsch; headings are not scored) against the GPS as imported (its fixes
    taken 1.55 s before their stamps, an offset the import measured without this component) at
    the estimate's times, in % of the GPS path: under the issue's 0.5 % goal (1.5 % target; 0.3 %
    when written), and the path's length within 2 % of the GPS's."""
    truth, est = edinburgh
    q, v = _gps_speed(truth)
    start = q[np.argmax((q > _gps_rest(truth)[-1][1]) & (v > 2.0))]  # the car drives off
    e = est[(est[:, 0] >= start) & (est[:, 0] <= truth[-1, 0])]
    g = np.column_stack([np.interp(e[:, 0], truth[:, 0], truth[:, 1]), np.interp(e[:, 0], truth[:, 0], truth[:, 2])])
    path_m = float(np.sum(np.hypot(*np.diff(g, axis=0).T)))
    assert path_m > 250.0
    p, q = e[:, 1:3] - e[:, 1:3].mean(axis=0), g - g.mean(axis=0)
    u, _, vt = np.linalg.svd(p.T @ q)
    rot = (u @ np.diag([1.0, np.sign(np.linalg.det(u @ vt))]) @ vt).T
    ate_m = float(np.sqrt(np.mean(np.sum((p @ rot.T - q) ** 2, axis=1))))
    print(f"\nDistortionOdometry on the Edinburgh drive: ATE {ate_m:.2f} m = {100 * ate_m / path_m:.2f} % of "
          f"{path_m:.0f} m of GPS path")
    assert 100.0 * ate_m / path_m <= 0.5, (ate_m, path_m)
    est_path_m = float(np.sum(np.hypot(*np.diff(e[:, 1:3], axis=0).T)))
    assert abs(est_path_m / path_m - 1.0) < 0.02
