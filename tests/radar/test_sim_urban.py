"""The `urban` scenario with the Navtech CTS350-X preset (issue 10 items 1-2): the sensor's
numbers, clockwise 4 Hz turns of 400 azimuths, a vehicle at 5-10 m/s with turns, RTK-GPS
truth on gps/pose, seedable; and the same graph as the real scans runs on it."""

import math

import numpy as np
import pytest

from impala_flow.testing import CollectingSink, run_components
from impala_radar.simulator.component import Simulator
from impala_radar.simulator.presets import NAVTECH, preset
from impala_radar.simulator.scenario import load_scenario


def test_navtech_preset_numbers():
    cfg = preset("navtech")
    assert cfg.range_per_bin_m == pytest.approx(0.0438, rel=1e-12)  # the resolution measured on Oxford
    assert cfg.n_bins == 3768 and cfg.beams_per_turn == 400 and cfg.rotation_hz == 4.0
    assert cfg.modulation_hz == cfg.beams_per_turn * cfg.rotation_hz  # one sweep per azimuth
    assert not cfg.doppler and 76e9 <= cfg.f0_hz - cfg.bandwidth_hz / 2 and cfg.f0_hz + cfg.bandwidth_hz / 2 <= 77e9
    assert cfg.beam_width_rad == pytest.approx(math.radians(1.8))
    assert cfg.range_of_bin_m(0) == pytest.approx(0.0219) and cfg.range_max_m == pytest.approx(165.04, abs=0.01)
    assert cfg is not NAVTECH  # a copy


def test_urban_world_route_and_truth():
    sc = load_scenario("urban", duration_s=60.0)
    traj = sc.trajectory
    t = np.arange(traj.start_ns, traj.start_ns + 60_000_000_000, 100_000_000)
    speed, yaw_rate = traj.velocity(t)
    assert speed.max() <= 10.0 + 1e-6 and np.percentile(speed[10:], 50) >= 5.0
    assert np.degrees(np.abs(yaw_rate)).max() > 10.0  # it turns (a 90 deg corner within 60 s)
    kinds = set(np.unique(sc.world.kind).tolist())
    assert len(sc.world.movers) >= 3 and len(kinds) >= 5  # facades, cars, trees, kerbs, posts...


@pytest.fixture(scope="module")
def one_second():
    sim = Simulator("sim", scenario="urban", duration_s=1.0, seed=4)
    beams, gps = CollectingSink("beams"), CollectingSink("gps")
    run_components(sim, beams, gps, connections=["sim.beams -> beams.x", "sim.gps -> gps.x"])
    return beams, gps


def test_urban_beams_are_clockwise_navtech_turns(one_second):
    beams, gps = one_second
    b = beams.values()
    assert len(b) == 4 * 400 and {x.config.name for x in b} == {"navtech-cts350x"}
    assert b[0].up.shape == (3768,)
    az = np.unwrap([x.azimuth_rad for x in b[:400]])
    assert np.allclose(np.diff(az), -2 * np.pi / 400)  # clockwise, like the real radar
    t = np.array(beams.times(), np.int64)
    assert np.diff(t[:401:400])[0] == 250_000_000  # 4 turns per second
    assert len(gps.values()) == 10 and gps.values()[0].frame  # RTK-GPS at 10 Hz on gps/pose


def test_urban_is_seeded(one_second):
    again = CollectingSink("beams")
    run_components(Simulator("sim", scenario="urban", duration_s=0.25, seed=4), again,
                   connections=["sim.beams -> beams.x"])
    first = one_second[0].values()[:400]
    assert all(np.array_equal(a.up, b.up) for a, b in zip(first, again.values(), strict=True))
