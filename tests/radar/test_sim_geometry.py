"""Scan geometry: trochoid distortion of a moving radar, a straight wall seen static,
shadowing behind buildings (seed 1 §2.3, §4.2)."""

import numpy as np
import pytest

from impala_radar.simulator.core import beam_azimuths_rad, beam_times_ns, simulate
from impala_radar.simulator.presets import IMPALA
from impala_radar.simulator.spectra import RadarParams, noise_power_per_bin_w
from impala_radar.simulator.world import WorldBuilder

from ._sim_helpers import StraightLine, peak_bin, range_velocity

WALL_X_M = 40.0
WALL_Z_M = 1.5


def _wall_world():
    b = WorldBuilder(np.random.default_rng(7))
    b.wall((WALL_X_M, -30.0), (WALL_X_M, 30.0), rcs_per_m=4.0, spacing_m=0.1, z_m=WALL_Z_M)
    return b.build()


def _wall_detections(speed_mps):
    """Per beam within +-12 deg of the heading: (t_ns, azimuth, R, V) from eq. (3)."""
    cfg = IMPALA
    traj = StraightLine(0.0, 0.0, 0.0, speed_mps, 1.0)
    beams = [m for _, p, m in simulate(_wall_world(), traj, cfg, np.random.default_rng(3))
             if p == "beams"]
    t_ns, az = beam_times_ns(0, 0, cfg), beam_azimuths_rad(cfg)
    sel = np.nonzero(np.cos(az) > np.cos(np.radians(12.0)))[0]
    out = []
    for j in sel:
        f_up = peak_bin(beams[j].up, 5, cfg.n_bins - 1) * cfg.bin_hz
        f_down = peak_bin(beams[j].down, 5, cfg.n_bins - 1) * cfg.bin_hz
        r_slant, v = range_velocity(f_up, f_down, cfg)
        r = np.sqrt(r_slant**2 - (WALL_Z_M - cfg.height_m) ** 2)
        out.append((t_ns[j], az[j], r, v))
    return traj, np.array(out)


def test_moving_radar_sees_the_wall_as_the_trochoid_predicts():
    v = 12.0
    traj, det = _wall_detections(v)
    t_s, az, r, v_rad = det[:, 0] * 1e-9, det[:, 1], det[:, 2], det[:, 3]
    x_radar = v * t_s  # the vehicle's position at each beam's own time
    r_pred = (WALL_X_M - x_radar) / np.cos(az)  # the beam from there hits the wall
    assert np.all(np.abs(r - r_pred) < IMPALA.range_resolution_m / 2)
    # Doppler of a static wall seen from the moving radar: V = -v cos(az)
    assert np.all(np.abs(v_rad + v * np.cos(az)) < IMPALA.velocity_resolution_mps / 2)
    # The uncorrected polar image (all beams placed at the turn's start pose) is distorted:
    # x_naive = R cos(az) = X_wall - v t, i.e. spread over v * (t_max - t_min) ~ 11.6 m...
    x_naive = r * np.cos(az)
    assert np.ptp(x_naive) > 0.8 * v * np.ptp(t_s)
    assert np.all(np.abs(x_naive - (WALL_X_M - x_radar)) < IMPALA.range_resolution_m / 2)
    # ... while placing each beam at its own pose straightens the wall again
    x_world = x_radar + r * np.cos(az)
    assert np.all(np.abs(x_world - WALL_X_M) < IMPALA.range_resolution_m / 2)


def test_static_radar_sees_the_wall_straight():
    _, det = _wall_detections(0.0)
    az, r = det[:, 1], det[:, 2]
    x, y = r * np.cos(az), r * np.sin(az)
    slope, intercept = np.polyfit(y, x, 1)  # the wall: x = a + b y
    resid = x - (intercept + slope * y)
    assert abs(slope) < 0.01
    assert intercept == pytest.approx(WALL_X_M, abs=IMPALA.range_resolution_m / 4)
    assert np.sqrt(np.mean(resid**2)) < IMPALA.range_resolution_m / 4


@pytest.mark.parametrize("with_wall", [False, True])
def test_target_behind_a_building_is_shadowed(with_wall):
    cfg = IMPALA
    b = WorldBuilder(np.random.default_rng(1))
    b.points([[60.0, 0.0]], cfg.height_m, 10.0, "point")
    if with_wall:
        b.wall((30.0, -10.0), (30.0, 10.0), rcs_per_m=2.0)
    traj = StraightLine(0.0, 0.0, 0.0, 0.0, 1.0)
    beams = [m for _, p, m in simulate(b.build(), traj, cfg, np.random.default_rng(2))
             if p == "beams"]
    k = int(round(60.0 / cfg.range_per_bin_m))
    around = np.array([[m.up[k - 3:k + 4], m.down[k - 3:k + 4]] for m in beams[-3:] + beams[:3]])
    ratio_db = 10 * np.log10(around.max() / noise_power_per_bin_w(cfg, RadarParams()))
    if with_wall:
        assert ratio_db < 12.0  # noise only (exponential tail over 84 cells)
    else:
        assert ratio_db > 30.0


def test_occlusion_is_per_line_of_sight():
    b = WorldBuilder(np.random.default_rng(0))
    b.building(0.0, 0.0, 10.0, 10.0)
    w = b.build()
    radar = np.array([[-30.0, 0.0], [0.0, -30.0]])[:, None, :]
    pts_x, pts_y = np.array([[20.0, 0.0, -5.0]]), np.array([[0.0, -20.0, 0.0]])
    vis = w.visible(radar, pts_x, pts_y)
    # from the west: (20, 0) hidden, (0, -20) visible, (-5, 0) on the near wall visible
    assert vis[0].tolist() == [False, True, True]
    # from the south: (20, 0) and (0, -20) visible, (-5, 0) on the west wall is seen
    # through the south wall (the ray crosses y = -5 at x = -4.2): hidden
    assert vis[1].tolist() == [True, True, False]
