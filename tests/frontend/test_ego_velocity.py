"""EgoVelocity: Doppler speed of the vehicle from one simulated turn (seed 1 §4.3.1)."""

import numpy as np
import pytest

from impala_flow.msgs import RadarDetections
from impala_flow.testing import CollectingSink, ScriptedSource, run_components
from impala_radar.frontend.ego_velocity import EgoVelocity, fit_ego_velocity
from impala_radar.frontend.pairer import detections_of_pairs
from impala_radar.frontend.pairing import pair_turn, xcorr_speed_prior
from impala_radar.sim.presets import IMPALA
from impala_radar.sim.simulate import simulate
from impala_radar.sim.vehicle import Trajectory
from impala_radar.sim.world import WorldBuilder

V_MPS = 5.0


def _turn(seed: int, movers: bool):
    """One simulated turn at 5 m/s along x through scattered strong points and grass."""
    rng = np.random.default_rng(seed)
    b = WorldBuilder(rng)
    xy = rng.uniform((-90.0, -90.0), (150.0, 90.0), (300, 2))
    b.points(xy[np.abs(xy[:, 1]) > 4.0], 1.0, rng.uniform(0.5, 5.0, (np.abs(xy[:, 1]) > 4.0).sum()), "point")
    b.clutter((-100.0, -100.0, 160.0, 100.0), 0.3, -22.0)
    if movers:  # an oncoming car and one overtaking, both in view all turn
        b.car_mover([[60.0, -3.0], [-100.0, -3.0]], 10.0, 0)
        b.car_mover([[-20.0, 3.0], [150.0, 3.0]], 12.0, 0)
    world = b.build()
    traj = Trajectory.from_waypoints(np.array([[0.0, 0.0], [200.0, 0.0]]), V_MPS, rest_at_ends=False)
    ev = [e for e in simulate(world, traj, IMPALA, rng, duration_ns=1_000_000_000) if e[1] == "beams"]
    t_ns = np.array([e[0] for e in ev], np.int64)
    up = np.stack([e[2].up for e in ev])
    down = np.stack([e[2].down for e in ev])
    az = np.array([e[2].azimuth_rad for e in ev])
    v_true = traj.velocity(t_ns)[0]
    assert np.allclose(v_true, V_MPS)
    p = pair_turn(up, down, az, IMPALA, xcorr_speed_prior(up, down, az, IMPALA))
    return detections_of_pairs(p, 0, t_ns, az, IMPALA)


@pytest.mark.parametrize("seed", [3, 4, 5])
@pytest.mark.parametrize("movers", [False, True])
def test_speed_from_doppler(movers, seed):
    """The error stays within 3 of the component's reported standard deviations (the formal
    std of the fit and the documented floor in quadrature), movers or not."""
    d = _turn(seed, movers)
    ego = EgoVelocity("ego")
    fit = fit_ego_velocity(d.azimuth_rad, d.radial_speed_mps, range_m=d.range_m, radar_height_m=IMPALA.height_m)
    std = float(np.hypot(fit.v0_std_mps, ego.std_floor_mps))
    err = fit.speed_mps - V_MPS
    print(f"\nmovers={movers}: {len(d.range_m)} detections, speed {fit.speed_mps:.4f} m/s "
          f"(error {err:+.4f}, reported std {std:.4f}), theta0 {np.degrees(fit.theta0_rad):.2f} deg, "
          f"{(~fit.inlier).sum()} off the curve")
    assert abs(err) <= 3.0 * std
    assert abs(fit.theta0_rad) < np.radians(1.0)  # straight driving, radar aligned


def test_movers_are_off_the_curve():
    rng = np.random.default_rng(0)
    az = rng.uniform(0, 2 * np.pi, 400)
    v = -V_MPS * np.cos(az) + rng.normal(0, 0.1, 400)
    v[:20] += rng.choice([-1, 1], 20) * rng.uniform(2.0, 10.0, 20)  # 5 % movers
    fit = fit_ego_velocity(az, v)
    assert abs(fit.speed_mps - V_MPS) < 0.03  # 0.1 / sqrt(190) x 3 (cos-weighted LS)
    assert (~fit.inlier[:20]).all() and fit.inlier[20:].mean() > 0.98


def test_component_outputs_speed_and_movers():
    rng = np.random.default_rng(1)
    n = 200
    az = rng.uniform(0, 2 * np.pi, n)
    cos_el = np.sqrt(1.0 - (1.3 / 20.0) ** 2)  # ground echoes at 20 m, radar 1.3 m high
    v = -V_MPS * np.cos(az) * cos_el + rng.normal(0, 0.1, n)
    v[:3] += 6.0
    d = RadarDetections(0, np.full(n, 10, np.int64), np.arange(n), az, np.full(n, 20.0), v, np.ones(n), np.ones(n))
    speed, movers = CollectingSink("s"), CollectingSink("m")
    run_components(ScriptedSource("src", [(10, "det", d)]), EgoVelocity("ego"), speed, movers,
                   connections=["src.det -> ego.detections", "ego.speed -> s.x", "ego.movers -> m.x"])
    (s,) = speed.values()
    # formal std of the cos-weighted least squares: 0.1 / sqrt(sum cos^2), the floor beside it
    inl = np.ones(n, bool)
    inl[:3] = False
    formal = 0.1 / (cos_el * np.sqrt(np.sum(np.cos(az[inl]) ** 2)))
    assert s.std_mps == pytest.approx(np.hypot(formal, 0.005), rel=0.25)
    assert abs(s.speed_mps - V_MPS) < 3.0 * s.std_mps
    flagged = set(movers.values()[0].beam.tolist())
    # the three movers, plus the 3-sigma tail of 200 Gaussian residuals (0.27 % x 200 ~ 0.5)
    assert {0, 1, 2} <= flagged and len(flagged) <= 5
