"""R-SLAM on panoramics of the radar simulator (Beynes scenario), against analytic answers.

The simulated images are physical power: 50 dB and more between near grass, far bushes and
metal sheds. These tests caught R-SLAM correlating that linear power (and weighting the
template by alpha(d) a second time): the correlation then rests on a few bright near speckle
cells and barely depends on the rotation, so a panoramic matched against a map made of
itself came back 0.15 deg and 2 cm off, and consecutive Beynes turns had 0.3 deg of heading
error per turn (3 % drift over 200 m). Matching the image in dB fixes both.
"""

import math

import cv2
import numpy as np
import pytest

from impala_flow.msgs import Grid
from impala_flow.testing import CollectingSink, run_components
from impala_radar.panoramic.component import PanoramicBuilder
from impala_radar.simulator.component import Simulator
from impala_slam.rslam.core import RSlamConfig, RSlamCore
from impala_slam.rslam.matching import match_to_map
from impala_slam.se2 import between
from impala_slam.tilemap import TileMap

cv2.setNumThreads(1)
TURNS = 7


@pytest.fixture(scope="module")
def beynes():
    """``TURNS`` motion-corrected panoramics of the Beynes mission and the true poses at t_ref."""
    sim = Simulator("sim", scenario="beynes", duration_s=TURNS + 0.5)
    sink = CollectingSink("sink")
    run_components(sim, PanoramicBuilder("pano"), sink, connections=[
        "sim.beams -> pano.beams", "sim.odometer -> pano.odometer", "sim.gyro -> pano.gyro", "pano.image -> sink.x"])
    grids = sink.values()
    truth = sim.built.trajectory.pose(np.array(sink.times(), np.int64) - sim.epoch_ns)  # scenario time
    return grids, truth


def test_a_panoramic_is_found_where_it_was_merged(beynes):
    """Map = one simulated panoramic merged at a pose off the cell grid; matching the same
    panoramic from a prediction 36 cm and 0.4 deg away must return that pose."""
    grids, _ = beynes
    core = RSlamCore()
    for k, th in ((2, 0.7), (6, 2.0)):
        img = core.amplitude(grids[k])
        core.map = TileMap(img.cell_m)
        true = (3.37, -1.21, th)
        core.update_map(img, true)
        m = match_to_map(core.map, img, (true[0] + 0.3, true[1] - 0.2, true[2] + math.radians(0.4)),
                         core.cfg.match, core.alpha)
        assert m.valid
        assert math.hypot(m.x_m - true[0], m.y_m - true[1]) < 0.01
        assert abs(math.degrees(m.theta_rad - true[2])) < 0.02


def test_consecutive_turns_match_the_true_motion(beynes):
    """R-SLAM's motion between consecutive turns against the simulator's truth."""
    grids, truth = beynes
    core = RSlamCore()
    est = [core.step(i, g)[0] for i, g in enumerate(grids)]
    err_xy, err_th = [], []
    for k in range(1, len(grids)):
        e, t = between(est[k - 1], est[k]), between(tuple(truth[k - 1]), tuple(truth[k]))
        err_xy.append(math.hypot(e[0] - t[0], e[1] - t[1]))
        err_th.append(math.degrees(e[2] - t[2]))
    rms_xy, rms_th = math.sqrt(np.mean(np.square(err_xy))), math.sqrt(np.mean(np.square(err_th)))
    print(f"\nper-turn errors: {rms_xy * 100:.1f} cm, {rms_th:.3f} deg rms; failures {core.failures}")
    assert core.failures == 0
    assert rms_xy < 0.03
    assert rms_th < 0.1


def test_map_is_the_weighted_mean_of_eq6():
    """A uniform panoramic merged from two poses: M = sum alpha A / sum alpha = A wherever
    it was seen, however far (eq. 6 as a running weighted mean); with the 1/N normaliser
    the map would fall off with the distance to the trajectory (the footprint of alpha)."""
    a = 7.0
    img = Grid(np.full((301, 301), a, np.float32), 0.2, -30.0, -30.0, "vehicle")
    for mean, flat in (("weighted", True), ("count", False)):
        core = RSlamCore(RSlamConfig(intensity="linear", map_update=mean, range_max_m=30.0))
        core.map = TileMap(0.2)
        core.update_map(img, (0.0, 0.0, 0.0))
        core.update_map(img, (4.3, 1.1, 0.5))
        m, seen = core.map.crop_with_support(-120, -120, 260, 260)
        vals = m[seen > 0]
        assert vals.size > 50_000
        assert np.allclose(vals, a, rtol=1e-5) == flat
