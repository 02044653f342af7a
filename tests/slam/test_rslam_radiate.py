"""R-SLAM on a real drive: the first 400 scans of RADIATE's Edinburgh sequence (2019-02-12), through
the commands a user runs (``impala-flow import radiate`` then ``impala-flow run graphs/oxford.yaml``),
scored against the sequence's GPS positions (issue 23, item 5).

The graph runs from 40 s to 90 s into the recording (200 turns): the car waits (the GPS stays within
a metre) until about 60 s, then drives about 230 m along a curving road at up to 10 m/s.

Truth: GPS positions only (metre-level consumer receiver; its heading is not used), aligned to the
estimate by a rigid least-squares fit (Kabsch, numpy's SVD, here). The GPS/IMU log runs late on the
radar log on this sequence; the import takes each fix 1.55 s before its stamp, an offset measured
without R-SLAM (bench/radiate_scale.py: the radar's speed from phase correlation against the GPS's).
The test scores the truth as imported, and checks that offset independently: shifting the imported
GPS times further over a 0.1 s grid of -1..+1 s (evo_ape's ``--t_offset``), R-SLAM's ATE is
smallest within 0.5 s of no shift.
"""

from __future__ import annotations

import numpy as np
import pytest

from impala_flow.cli import main
from impala_flow.io._reader import MissionReader

from .test_oxford import GRAPH

START_S, END_S = 40.0, 90.0  # seconds into the recording the graph runs over (it starts at rest)


def _positions(path, topic: str) -> tuple[np.ndarray, np.ndarray]:
    with MissionReader(path) as r:
        rows = [(m.t_ns, m.data.x_m, m.data.y_m) for m in r.messages([topic])]
    a = np.array(rows, dtype=np.float64)
    return a[:, 0].astype(np.int64), a[:, 1:]


def _ate(est: np.ndarray, gps: np.ndarray) -> float:
    """RMS position error after the rigid (rotation + translation) least-squares fit of est on gps."""
    ce, cg = est.mean(0), gps.mean(0)
    u, _, vt = np.linalg.svd((est - ce).T @ (gps - cg))
    d = np.sign(np.linalg.det(u @ vt))
    rot = (u @ np.diag([1.0, d]) @ vt).T
    return float(np.sqrt(np.mean(np.sum(((est - ce) @ rot.T + cg - gps) ** 2, axis=1))))


@pytest.fixture(scope="module")
def drive(edinburgh_mission, tmp_path_factory):
    mission = edinburgh_mission  # imported once per session (tests/conftest.py)
    out = tmp_path_factory.mktemp("edinburgh-rslam") / "out"
    assert main(["run", str(GRAPH), "--var", f"mission={mission}", "--var", f"out={out}",
                 "--var", f"start_s={START_S}", "--var", f"end_s={END_S}", "--no-progress"]) == 0
    t_gps, gps = _positions(mission, "truth/pose")
    t_est, est = _positions(out / "oxford.mcap", "slam/pose")
    with MissionReader(mission) as r:
        t0 = next(iter(r.messages(["radar/beams"]))).t_ns
    return t0, t_gps, gps, t_est, est


def _gps_at_rest(t_gps: np.ndarray, gps: np.ndarray) -> tuple[int, int]:
    """The longest span over which the GPS moves less than 0.5 m in any 2 s."""
    j = np.minimum(np.searchsorted(t_gps, t_gps + 2_000_000_000), len(t_gps) - 1)
    still = np.hypot(*(gps[j] - gps).T) < 0.5
    best, start = (0, 0), None
    for i, s in enumerate(np.append(still, False)):
        if s and start is None:
            start = i
        elif not s and start is not None:
            if t_gps[i - 1] - t_gps[start] > best[1] - best[0]:
                best = (int(t_gps[start]), int(t_gps[i - 1]) + 2_000_000_000)
            start = None
    return best


def test_the_car_waiting_does_not_move_the_estimate(drive):
    t0, t_gps, gps, t_est, est = drive
    a, b = _gps_at_rest(t_gps, gps[:, :2])
    a, b = max(a, t_est[0]) + 2_500_000_000, b - 2_500_000_000  # margins for the GPS clock offset
    assert b - a > 8e9, "the recording's head should hold a stop of more than 8 s after the graph's start"
    rest = (t_est >= a) & (t_est <= b)
    g = gps[(t_gps >= a) & (t_gps <= b)]
    gps_scatter = float(np.sqrt(np.mean(np.sum((g - g.mean(0)) ** 2, axis=1))))
    drift = float(np.max(np.hypot(*(est[rest] - est[rest][0]).T)))
    print(f"\nat rest {1e-9 * (a - t0):.1f}-{1e-9 * (b - t0):.1f} s ({rest.sum()} turns): the estimate moves "
          f"{100 * drift:.1f} cm at most, the GPS scatters {100 * gps_scatter:.0f} cm RMS")
    assert rest.sum() > 30
    # the GPS cannot tell a car at rest from one moving less than its scatter: the estimate must
    # stay within it (measured: 9 cm against 17 cm)
    assert drift < gps_scatter


def test_the_drive_is_within_the_ate_target_against_the_gps(drive):
    t0, t_gps, gps, t_est, est = drive
    moving = t_est - t0 >= 60e9
    scores = {}
    for off in np.arange(-1.0, 1.01, 0.1):
        t = t_est[moving] + int(round(off * 1e9))
        inside = (t >= t_gps[0]) & (t <= t_gps[-1])
        g = np.column_stack([np.interp(t[inside], t_gps, gps[:, k]) for k in (0, 1)])
        path = float(np.sum(np.hypot(*np.diff(g, axis=0).T)))
        scores[round(float(off), 1)] = (_ate(est[moving][inside], g), path)
    best = min(scores, key=lambda k: scores[k][0])
    ate, path = scores[0.0]
    print(f"\nR-SLAM on the Edinburgh drive: ATE {ate:.2f} m = {100 * ate / path:.2f} % of {path:.0f} m of GPS path "
          f"(smallest with the GPS times shifted {best:+.1f} s more: {scores[best][0]:.2f} m)")
    assert path > 200.0
    assert abs(best) <= 0.5  # the import's GPS clock offset, measured without R-SLAM, holds for R-SLAM
    # target 1.5 % of the path (goal 0.5 %): 0.36 % when written
    assert ate < 0.0075 * path
