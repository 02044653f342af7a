"""R-SLAM against synthetic panoramics of known poses, and dead reckoning against arcs."""

import math

import cv2
import numpy as np
import pytest

from impala_flow._component import Output, Source
from impala_flow.msgs import Grid, Pose2D
from impala_flow.testing import CollectingSink, ScriptedSource, run_components
from impala_msgs import Speed, YawRate
from impala_slam.dead_reckoning.component import DeadReckoning
from impala_slam.rslam.component import RSlam
from impala_slam.rslam.core import RSlamConfig, RSlamCore
from impala_slam.rslam.matching import MatchParams, match_to_map
from impala_slam.se2 import between
from impala_slam.synthetic import SyntheticWorld, synthetic_mission
from impala_slam.tilemap import TileMap

cv2.setNumThreads(1)


@pytest.fixture(scope="module")
def world():
    rng = np.random.default_rng(7)
    return SyntheticWorld.random(rng, (-90, 90), (-90, 90), 0.03, 3)


@pytest.mark.parametrize("true_xyt", [(1.13, -0.42, 1.3), (-0.61, 0.87, -0.7), (0.05, 1.45, 0.2)])
def test_matching_recovers_a_known_displacement(world, true_xyt):
    rng = np.random.default_rng(3)
    core = RSlamCore(RSlamConfig(range_max_m=50.0, db_floor_quantile=0.5))  # points over noise: 0 dB = median
    core.step(0, world.render((0.0, 0.0, 0.0), rng, radius_m=50.0))
    true = (true_xyt[0], true_xyt[1], math.radians(true_xyt[2]))
    pred = (true[0] - 0.3, true[1] + 0.25, true[2] - math.radians(0.6))  # odometry off by 39 cm, 0.6 deg
    m = match_to_map(core.map, core.amplitude(world.render(true, rng, radius_m=50.0)), pred,
                     MatchParams(match_range_m=50.0), core.alpha)
    assert m.valid
    assert math.hypot(m.x_m - true[0], m.y_m - true[1]) < 0.06
    assert abs(math.degrees(m.theta_rad - true[2])) < 0.12
    sx, sy, st = np.sqrt(np.diag(m.cov_xyt))
    assert 0.0 < sx < 1.0 and 0.0 < sy < 1.0 and 0.0 < st < math.radians(2.0)


def test_tiles_grow_with_the_area_mapped_and_eq6_averages():
    tm = TileMap(0.5, tile_m=16.0)  # 32 x 32 cells per tile
    ones = np.ones((10, 10), np.float32)
    tm.add(0, 0, 2.0 * ones, ones > 0)
    tm.add(0, 0, 4.0 * ones, ones > 0)
    assert tm.n_tiles == 1
    assert np.allclose(tm.crop(0, 0, 10, 10), 3.0)  # (2 + 4) / N, N = 2
    tm.add(1024, -1024, ones, ones > 0)  # far away: one more tile, not the box between
    assert tm.n_tiles == 2
    assert tm.nbytes == 2 * 2 * 32 * 32 * 4
    tm.add(30, 30, ones, ones > 0)  # straddles 4 tiles, one of them existing
    assert tm.n_tiles == 5
    assert np.allclose(tm.crop(1024, -1024, 10, 10), 1.0)
    assert tm.crop(-50, -50, 5, 5).sum() == 0.0


class _Mission(Source):
    image = Output(Grid)
    odometer = Output(Speed)
    gyro = Output(YawRate)
    truth = Output(Pose2D)

    def generate(self):
        return synthetic_mission(12, seed=2, radius_m=40.0, speed_scale_err=0.05, gyro_bias_radps=0.01)


def test_rslam_component_beats_dead_reckoning_on_a_synthetic_mission():
    slam = RSlam("slam", range_max_m=40.0, match_range_m=40.0, map_period_s=5.0, db_floor_quantile=0.5)
    sink = CollectingSink("sink", ports=["pose", "map", "truth", "dr"])
    run_components(_Mission("m"), slam, DeadReckoning("dr", period_s=1.0), sink, connections=[
        "m.image -> slam.image", "m.odometer -> dr.odometer", "m.gyro -> dr.gyro", "slam.pose -> sink.pose",
        "slam.map -> sink.map", "m.truth -> sink.truth", "dr.pose -> sink.dr"])
    poses, truth = sink.by_port["pose"], sink.by_port["truth"]
    assert len(poses) == 12 and all(p.data.frame == "map" and p.data.cov_xyt.shape == (3, 3) for p in poses)
    assert len(sink.by_port["map"]) >= 2 and sink.by_port["map"][-1].data.frame == "map"
    truth_at = {s.timestamp: s.data for s in truth}

    def rel(a, b):  # pose b in the frame of pose a: (x, y, theta)
        return between((a.x_m, a.y_m, a.theta_rad), (b.x_m, b.y_m, b.theta_rad))

    def errors(samples):
        """Full pose errors (m, deg) of each sample relative to the first one, against the truth's
        (the map frame is the odometry frame of the first turn): lateral and heading too."""
        samples = [s for s in samples if s.timestamp in truth_at and s.timestamp >= poses[0].timestamp]
        first, t0 = samples[0].data, truth_at[samples[0].timestamp]
        pos, head = [], []
        for s in samples[1:]:
            e, g = rel(first, s.data), rel(t0, truth_at[s.timestamp])
            pos.append(math.hypot(e[0] - g[0], e[1] - g[1]))
            head.append(abs(math.degrees(math.remainder(e[2] - g[2], 2 * math.pi))))
        return max(pos), max(head)

    slam_pos, slam_head = errors(poses)
    dr_pos, dr_head = errors(sink.by_port["dr"])
    print(f"\nsynthetic mission: R-SLAM {slam_pos:.3f} m / {slam_head:.3f} deg, "
          f"dead reckoning {dr_pos:.3f} m / {dr_head:.3f} deg")
    assert slam_pos < 0.1 and slam_head < 0.3
    assert dr_pos > 0.3 and dr_head > 2 * slam_head  # 5 % scale error, 0.01 rad/s gyro bias


def test_dead_reckoning_follows_an_exact_circle():
    v, w = 2.0, 0.3  # 2 m/s on a circle of radius v / w
    t = [int(k * 50_000_000) for k in range(201)]  # 10 s at 20 Hz
    src = ScriptedSource("s", [(ti, "odo", Speed(v)) for ti in t] + [(ti, "gyro", YawRate(w)) for ti in t])
    src.script.sort(key=lambda x: x[0])
    sink = CollectingSink("sink")
    run_components(src, DeadReckoning("dr", period_s=0.5, theta0_rad=0.2), sink,
                   connections=["s.odo -> dr.odometer", "s.gyro -> dr.gyro", "dr.pose -> sink.x"])
    for s in sink.samples[1:]:
        ts = s.timestamp * 1e-9
        th = 0.2 + w * ts
        x = (math.sin(th) - math.sin(0.2)) * v / w
        y = (math.cos(0.2) - math.cos(th)) * v / w
        assert s.data.x_m == pytest.approx(x, abs=1e-9)
        assert s.data.y_m == pytest.approx(y, abs=1e-9)
        assert math.cos(s.data.theta_rad - th) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize(("size", "n", "m"), [(640, 609, 601), (320, 311, 301), (96, 40, 33), (64, 20, 11), (5, 4, 2)])
def test_corner_of_the_inverse_dft_equals_the_direct_correlation(size, n, m):
    """The k x k corner the correlator reads (k = n - m + 1 shifts), from the two spectra through
    the partial inverse of their product, against the correlation summed cell by cell in float64."""
    from impala_slam.rslam.matching import _corner_idft

    rng = np.random.default_rng(size + m)
    win = np.zeros((size, size), np.float32)
    tpl = np.zeros((size, size), np.float32)
    win[:n, :n] = rng.random((n, n))
    tpl[:m, :m] = rng.standard_normal((m, m))
    k = n - m + 1
    direct = np.array([[np.sum(win[i:i + m, j:j + m].astype(np.float64) * tpl[:m, :m]) for j in range(k)]
                       for i in range(k)])
    scale = np.sqrt(np.sum(win[:n, :n].astype(np.float64) ** 2) * np.sum(tpl.astype(np.float64) ** 2))
    assert np.max(np.abs(_corner_idft(cv2.dft(win), cv2.dft(tpl), k) - direct)) < 1e-6 * scale
