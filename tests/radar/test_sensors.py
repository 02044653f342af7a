"""Proprioceptive sensors: timing contract and statistics against their parameters."""

import numpy as np
import pytest

import impala_msgs
from impala_radar.simulator.sensors import Gps, Gyro, Odometer, make_sensors, sample_times_ns
from impala_radar.simulator.vehicle import Trajectory

STRAIGHT = Trajectory.from_waypoints([[0.0, 0.0], [400.0, 0.0]], 2.0, rest_at_ends=False)
LOOP = Trajectory.from_waypoints([[0.0, 0.0], [40.0, 0.0], [40.0, 30.0], [0.0, 30.0]], 3.0,
                                 closed=True)


def _collect(sensor, traj, seed=0, start=None, end=None):
    rng = np.random.default_rng(seed)
    start = traj.start_ns if start is None else start
    end = traj.end_ns if end is None else end
    items = list(sensor.samples(traj, rng, start, end))
    return np.array([t for t, _ in items], dtype=np.int64), [m for _, m in items]


@pytest.mark.parametrize("sensor", [Odometer(), Gyro(), Gps()])
def test_timestamps_are_integer_multiples_of_the_period(sensor):
    start, end = 123_456_789, 3_000_000_001
    t, items = _collect(sensor, LOOP, start=start, end=end)
    period = round(1e9 / sensor.rate_hz)
    assert all(type(x) is int for x in t.tolist())
    assert np.all(t % period == 0) and np.all(np.diff(t) == period)
    assert t[0] >= start and t[0] - period < start and t[-1] < end <= t[-1] + period
    assert all(isinstance(m, sensor.msg_type) for m in items)


def test_sample_times_edges():
    assert sample_times_ns(10.0, 0, 300_000_000).tolist() == [0, 100_000_000, 200_000_000]
    assert sample_times_ns(10.0, 1, 100_000_001).tolist() == [100_000_000]


def test_same_seed_same_samples():
    odo = Odometer(slip_rate_per_s=0.5)
    a = [m.speed_mps for m in _collect(odo, LOOP, seed=3)[1]]
    b = [m.speed_mps for m in _collect(odo, LOOP, seed=3)[1]]
    c = [m.speed_mps for m in _collect(odo, LOOP, seed=4)[1]]
    assert a == b and a != c


def test_odometer_scale_error_and_noise():
    odo = Odometer(scale_error=0.03, noise_mps=0.05, slip_rate_per_s=0.0)
    t, items = _collect(odo, STRAIGHT)
    measured = np.array([m.speed_mps for m in items])
    true_v, _ = STRAIGHT.velocity(t)
    dt = 1.0 / odo.rate_hz
    ratio = measured.sum() * dt / (true_v.sum() * dt)
    # noise std of the ratio: noise * sqrt(N) / sum(v)
    bound = 4 * 0.05 * np.sqrt(len(t)) / true_v.sum()
    assert abs(ratio - 1.03) < bound
    residual = measured - 1.03 * true_v
    n = len(residual)
    assert abs(residual.std(ddof=1) / 0.05 - 1.0) < 4 / np.sqrt(2 * (n - 1))


def test_odometer_slip_bursts_at_configured_rate():
    rate, duration, factor = 0.2, 0.5, 1.5
    odo = Odometer(scale_error=0.0, noise_mps=0.0, slip_rate_per_s=rate,
                   slip_duration_s=duration, slip_factor=factor)
    t, items = _collect(odo, STRAIGHT, seed=11)
    measured = np.array([m.speed_mps for m in items])
    true_v, _ = STRAIGHT.velocity(t)
    slipping = np.isclose(measured, factor * true_v) & (true_v > 0)
    assert np.all(slipping | np.isclose(measured, true_v))
    span_s = (t[-1] - t[0]) * 1e-9
    # runs of slipping samples: overlapping bursts merge, so a run starts at rate*exp(-rate*d)
    runs = np.count_nonzero(np.diff(slipping.astype(int)) == 1) + int(slipping[0])
    expected_runs = rate * np.exp(-rate * duration) * span_s
    assert abs(runs - expected_runs) < 4 * np.sqrt(expected_runs)
    # fraction of time slipping of a Poisson burst process: 1 - exp(-rate * d)
    assert slipping.mean() == pytest.approx(1 - np.exp(-rate * duration), abs=0.04)


def test_gyro_bias_and_noise():
    gyro = Gyro(bias_radps=0.01, noise_radps=0.003, bias_walk_radps_per_sqrt_s=0.0)
    still = Trajectory.stationary(0.0, 0.0, 0.0, 120.0)
    _, items = _collect(gyro, still)
    w = np.array([m.yaw_rate_radps for m in items])
    n = len(w)
    assert abs(w.mean() - 0.01) < 4 * 0.003 / np.sqrt(n)
    assert abs(w.std(ddof=1) / 0.003 - 1.0) < 4 / np.sqrt(2 * (n - 1))


def test_gyro_measures_the_yaw_rate_while_moving():
    gyro = Gyro(bias_radps=0.0, noise_radps=0.001, bias_walk_radps_per_sqrt_s=0.0)
    t, items = _collect(gyro, LOOP)
    w = np.array([m.yaw_rate_radps for m in items])
    _, true_w = LOOP.velocity(t)
    assert np.abs(w - true_w).max() < 6 * 0.001
    assert np.sum(w) / gyro.rate_hz == pytest.approx(2 * np.pi, abs=0.02)  # one loop


def test_gyro_bias_random_walk():
    walk = 0.002
    gyro = Gyro(bias_radps=0.0, noise_radps=0.0, bias_walk_radps_per_sqrt_s=walk)
    still = Trajectory.stationary(0.0, 0.0, 0.0, 100.0)
    _, items = _collect(gyro, still)
    w = np.array([m.yaw_rate_radps for m in items])
    steps = np.diff(w)
    expected = walk * np.sqrt(1.0 / gyro.rate_hz)
    assert abs(steps.std(ddof=1) / expected - 1.0) < 4 / np.sqrt(2 * (len(steps) - 1))
    assert abs(steps.mean()) < 4 * expected / np.sqrt(len(steps))


def test_gps_truth_noise_and_covariance():
    gps = Gps(sigma_m=0.02)
    t, items = _collect(gps, LOOP)
    truth = LOOP.pose(t)
    xy = np.array([[m.x_m, m.y_m] for m in items])
    err = xy - truth[:, :2]
    n = err.size
    assert abs(err.std(ddof=1) / 0.02 - 1.0) < 4 / np.sqrt(2 * (n - 1))
    assert np.abs(err.mean(axis=0)).max() < 4 * 0.02 / np.sqrt(len(t))
    assert np.allclose([m.theta_rad for m in items], truth[:, 2])
    assert all(m.frame == "map" for m in items)
    assert np.allclose(items[0].cov_xyt, np.diag([0.02**2, 0.02**2, 0.0]))


def test_make_sensors():
    sensors = make_sensors({"odometer": {"scale_error": 0.05}, "gyro": {}, "gps": None})
    assert set(sensors) == {"odometer", "gyro", "gps"}
    assert sensors["odometer"].scale_error == 0.05 and sensors["odometer"].rate_hz == 50.0
    assert isinstance(sensors["gps"], Gps) and sensors["gps"].port == "gps"
    assert sensors["gyro"].msg_type is impala_msgs.YawRate
    with pytest.raises(ValueError, match="'scale_eror'") as info:
        make_sensors({"odometer": {"scale_eror": 0.05}})
    assert "\n" not in str(info.value)
    with pytest.raises(ValueError, match="'lidar'"):
        make_sensors({"lidar": {}})
