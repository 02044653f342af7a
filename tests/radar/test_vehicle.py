"""Vehicle trajectories: limits respected, pose = integral of velocity, loops close."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from impala_radar.simulator.vehicle import Trajectory

RECT = np.array([[0.0, 0.0], [60.0, 0.0], [60.0, 30.0], [0.0, 30.0]])
ZIGZAG = np.array([[0.0, 0.0], [25.0, 0.0], [25.0, 25.0], [50.0, 25.0], [55.0, 0.0]])


def _geometric_curvature(traj: Trajectory, step_ns: int = 20_000_000) -> tuple:
    """Curvature of the (x, y) track by finite differences (independent of theta)."""
    t = np.arange(traj.start_ns, traj.end_ns, step_ns)
    xy = traj.pose(t)[:, :2]
    dt = step_ns * 1e-9
    d1 = np.gradient(xy, dt, axis=0)
    d2 = np.gradient(d1, dt, axis=0)
    speed = np.hypot(d1[:, 0], d1[:, 1])
    moving = speed > 0.5
    kappa = (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])[moving] / speed[moving] ** 3
    return kappa, speed


@pytest.mark.parametrize("kappa_max", [0.1, 0.2, 0.5])
def test_curvature_never_exceeds_limit(kappa_max):
    traj = Trajectory.from_waypoints(ZIGZAG, 4.0, max_curvature_1pm=kappa_max)
    kappa, _ = _geometric_curvature(traj)
    assert np.abs(kappa)[2:-2].max() <= 1.02 * kappa_max
    # the corners are really turned: some curvature reaches the neighbourhood of the limit
    assert np.abs(kappa).max() > 0.5 * kappa_max


def test_speed_respects_accel_and_lateral_limits():
    traj = Trajectory.from_waypoints(RECT, 8.0, max_accel_mps2=2.0, max_lateral_accel_mps2=1.5,
                                     closed=True)
    t = np.arange(traj.start_ns, traj.end_ns, 5_000_000)
    v, w = traj.velocity(t)
    accel = np.diff(v) / 5e-3
    assert np.abs(accel).max() <= 2.0 * 1.001
    assert np.max(v * np.abs(w)) <= 1.5 * 1.01
    assert v.max() == pytest.approx(8.0, rel=1e-3)  # the long straight reaches the target
    assert v[0] < 0.1 and v[-1] < 0.1  # starts and ends at rest


def test_per_waypoint_speeds():
    wp = np.array([[0.0, 0.0], [100.0, 0.0], [200.0, 0.0]])
    traj = Trajectory.from_waypoints(wp, [2.0, 6.0, 6.0], rest_at_ends=False, max_accel_mps2=5.0)
    t = np.arange(traj.start_ns, traj.end_ns, 10_000_000)
    v, _ = traj.velocity(t)
    x = traj.pose(t)[:, 0]
    assert v[np.argmin(np.abs(x - 50.0))] == pytest.approx(4.0, abs=0.05)
    assert v[np.argmin(np.abs(x - 150.0))] == pytest.approx(6.0, abs=0.05)


def test_integrating_velocity_reproduces_pose():
    traj = Trajectory.from_waypoints(ZIGZAG, 5.0, start_t_ns=1_000_000_000)
    t0 = traj.start_ns

    def unicycle(t_s, state):
        v, w = traj.velocity(t0 + int(round(t_s * 1e9)))
        return [v * np.cos(state[2]), v * np.sin(state[2]), w]

    duration_s = (traj.end_ns - t0) * 1e-9
    t_eval = np.linspace(0.0, duration_s, 50)
    # the yaw rate steps slightly every 5 cm arc, so the adaptive solver is the limit here
    sol = solve_ivp(unicycle, (0.0, duration_s), traj.pose(t0), t_eval=t_eval,
                    method="LSODA", rtol=1e-6, atol=1e-6)
    truth = traj.pose(t0 + np.round(t_eval * 1e9).astype(np.int64))
    assert np.abs(sol.y[0] - truth[:, 0]).max() < 0.01
    assert np.abs(sol.y[1] - truth[:, 1]).max() < 0.01
    dtheta = (sol.y[2] - truth[:, 2] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(dtheta).max() < 1e-3
    assert np.ptp(truth[:, 2]) > 1.0  # the check covers real turns


def test_length_is_summed_path_length_and_pose_is_vectorised():
    traj = Trajectory.from_waypoints(ZIGZAG, 3.0)
    t = np.arange(traj.start_ns, traj.end_ns + 1, 2_000_000)
    t = np.append(t, traj.end_ns)
    xy = traj.pose(t)[:, :2]
    assert np.sum(np.hypot(*np.diff(xy, axis=0).T)) == pytest.approx(traj.length_m, rel=1e-4)
    grid = t[:200].reshape(10, 20)
    assert traj.pose(grid).shape == (10, 20, 3)
    assert np.allclose(traj.pose(grid)[3, 7], traj.pose(int(grid[3, 7])))
    theta = traj.pose(t)[:, 2]
    assert theta.min() >= -np.pi and theta.max() < np.pi


def test_closed_loop_closes():
    traj = Trajectory.from_waypoints(RECT, 5.0, closed=True)
    start, end = traj.pose(np.array([traj.start_ns, traj.end_ns]))
    assert np.hypot(*(end[:2] - start[:2])) < 1e-3
    assert abs((end[2] - start[2] + np.pi) % (2 * np.pi) - np.pi) < 1e-3
    # a rectangle loop rounded at the corners is a bit shorter than its perimeter
    assert 170.0 < traj.length_m < 180.0


def test_stationary_and_outside_times():
    traj = Trajectory.stationary(3.0, -2.0, 1.0, 10.0, start_t_ns=5)
    assert traj.start_ns == 5 and traj.end_ns == 5 + 10_000_000_000
    assert traj.length_m == 0.0
    assert np.allclose(traj.pose(np.array([0, 6, 10**12])), [3.0, -2.0, 1.0])
    v, w = traj.velocity(np.arange(5, traj.end_ns, 10**9))
    assert not v.any() and not w.any()
    moving = Trajectory.from_waypoints(ZIGZAG, 3.0)
    v, w = moving.velocity(np.array([moving.start_ns - 1, moving.end_ns + 1]))
    assert not v.any() and not w.any()
    assert np.allclose(moving.pose(moving.end_ns + 10**9), moving.pose(moving.end_ns))


def test_truncated_by_duration_and_length():
    traj = Trajectory.from_waypoints(ZIGZAG, 3.0)
    by_time = traj.truncated(duration_ns=7_000_000_000)
    assert by_time.end_ns == traj.start_ns + 7_000_000_000
    t = np.arange(traj.start_ns, by_time.end_ns, 3_000_000)
    assert np.allclose(by_time.pose(t), traj.pose(t), atol=1e-9)
    by_length = traj.truncated(length_m=30.0)
    assert by_length.length_m == pytest.approx(30.0, abs=0.01)
    both = traj.truncated(duration_ns=10**15, length_m=10.0)
    assert both.length_m == pytest.approx(10.0, abs=0.01)


def test_infeasible_waypoints_still_respect_curvature():
    tiny = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [0.0, 3.0]])
    traj = Trajectory.from_waypoints(tiny, 2.0, closed=True, max_curvature_1pm=0.2)
    kappa, _ = _geometric_curvature(traj, step_ns=10_000_000)
    assert np.abs(kappa)[2:-2].max() <= 1.02 * 0.2


def test_bad_inputs():
    with pytest.raises(ValueError):
        Trajectory.from_waypoints([[0.0, 0.0]], 1.0)
    with pytest.raises(ValueError):
        Trajectory.from_waypoints(ZIGZAG, 0.0)
