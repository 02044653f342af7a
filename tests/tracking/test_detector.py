"""tracking.MoverDetector through the component runner: ego-Doppler removal (seed 1 eq. 7),
clustering, ghost absorption, frame placement, against formulas (issue 13 item 1)."""

from __future__ import annotations

import numpy as np

from impala_flow.msgs import Pose2D
from impala_flow.testing import CollectingSink, ScriptedSource, run_components
from impala_msgs import RadarDetections, Speed
from impala_tracking.detector.component import MoverDetector
from impala_tracking.detector.core import ground_radial_speed_mps

T_NS = 1_000_000_000


def _turn(speed_mps: float, mover_v_mps: float, mover_range_m: float, mover_beams: list[int]):
    """A turn of 360 beams: a static target on every beam (radial speed -s cos(theta) at 50 m,
    raised), a mover over ``mover_beams`` whose ground radial speed is ``mover_v_mps``, and a
    2-beam ghost pair 1.5 m beyond it whose radial speed is 6 m/s off."""
    beam = np.arange(360)
    az = np.radians(beam.astype(float))
    rows = [(b, a, 50.0, -speed_mps * np.cos(a), 1.0) for b, a in zip(beam, az, strict=True)]
    for b in mover_beams:
        rows.append((b, az[b], mover_range_m, mover_v_mps - speed_mps * np.cos(az[b]), 10.0))
    for b in mover_beams[:2]:
        rows.append((b, az[b], mover_range_m + 1.5, mover_v_mps + 6.0 - speed_mps * np.cos(az[b]), 3.0))
    b, a, r, v, amp = (np.array(x) for x in zip(*rows, strict=True))
    t = (b * T_NS // 360).astype(np.int64)
    return RadarDetections(0, t, b.astype(np.int64), a, r, v, amp, np.ones(len(b)))


def test_static_world_removed_mover_kept_with_its_ground_radial_speed_in_the_pose_frame():
    speed, v_mover, r_mover, beams = 6.0, -4.0, 40.0, [28, 29, 30, 31, 32]
    pose = Pose2D(100.0, -20.0, np.radians(30.0), frame="map")
    script = [(0, "pose", pose), (0, "speed", Speed(speed, 0.01)), (T_NS, "pose", pose),
              (T_NS - 1, "det", _turn(speed, v_mover, r_mover, beams))]
    sink = CollectingSink("sink")
    run_components(ScriptedSource("src", sorted(script, key=lambda s: s[0])), MoverDetector("det"), sink,
                   connections=["src.det -> det.detections", "src.speed -> det.speed", "src.pose -> det.pose",
                                "det.movers -> sink.x"])
    (m,) = sink.values()
    assert len(m.t_ns) == 1  # 360 static echoes gone, the ghost pair folded into the mover
    assert abs(m.radial_speed_mps[0] - v_mover) < 1e-9  # the ghost's Doppler is not averaged in
    # amplitude-weighted centroid: 5 mover beams of amplitude 10, the ghost's 2 beams of 3
    w = np.array([10.0] * 5 + [3.0] * 2)
    az_deg = np.array(beams + beams[:2], float)
    bearing = pose.theta_rad + np.radians(w @ az_deg / w.sum())  # small arc: the mean angle is the circular one
    r = w @ np.array([r_mover] * 5 + [r_mover + 1.5] * 2) / w.sum()
    expect = np.array([pose.x_m, pose.y_m]) + r * np.array([np.cos(bearing), np.sin(bearing)])
    assert np.hypot(*(m.xy_m[0] - expect)) < 0.05
    assert m.frame == "map" and np.allclose(m.sensor_xy_m, [pose.x_m, pose.y_m])
    assert m.n_beams[0] == 7 and np.all(np.linalg.eigvalsh(m.cov_xy[0]) > 0)


def test_ego_doppler_of_ground_and_raised_echoes():
    az = np.radians([0.0, 45.0, 90.0, 180.0])
    rng = np.array([5.0, 20.0, 50.0, 10.0])
    s, h = 5.0, 1.3
    f_ground = np.sqrt(1 - (h / rng) ** 2)  # ground / slant range
    raised, ground = ground_radial_speed_mps(-s * np.cos(az) * f_ground, az, rng, s, h)
    assert np.allclose(ground, 0.0, atol=1e-12)
    assert np.allclose(raised, s * np.cos(az) * (1 - f_ground), atol=1e-12)
