"""No warning, no NaN on degenerate inputs (issue 9 item 5): empty, constant, single-echo and
subnormal images through R-SLAM, silent beams through the panoramic builder. Every pose
emitted is finite; the conditions are counted in the components' summaries. (pytest turns
any RuntimeWarning into an error for the whole suite.)"""

import numpy as np

from impala_flow.msgs import Grid, RadarBeam
from impala_flow.testing import CollectingSink, ScriptedSource, run_components
from impala_radar.frontend.panoramic_builder import PanoramicBuilder
from impala_radar.sim.presets import IMPALA
from impala_slam.rslam import RSlam

N = 201


def _grid(data):
    return Grid(np.asarray(data, np.float32), 0.2, -20.0, -20.0, "vehicle", None)


def _rslam(images):
    src = ScriptedSource("src", [(k * 1_000_000_000, "img", g) for k, g in enumerate(images)])
    poses, twists = CollectingSink("poses"), CollectingSink("twists")
    slam = RSlam("slam", range_max_m=20.0)
    run_components(src, slam, poses, twists,
                   connections=["src.img -> slam.image", "slam.pose -> poses.x", "slam.twist -> twists.x"])
    return slam, poses.values(), twists.values()


def test_rslam_on_empty_constant_single_echo_and_subnormal_images():
    rng = np.random.default_rng(0)
    scene = rng.exponential(1.0, (N, N)) * (rng.random((N, N)) < 0.2)
    single = np.zeros((N, N))
    single[100, 150] = 5.0
    subnormal = np.where(scene > 0, 1e-42, 0.0)  # below float32's normal range
    nan_cell = scene.copy()
    nan_cell[5, 5] = np.nan
    images = [_grid(scene), _grid(np.zeros((N, N))), _grid(np.full((N, N), 3.0)), _grid(single),
              _grid(subnormal), _grid(nan_cell), _grid(scene)]
    slam, poses, twists = _rslam(images)
    assert len(poses) == len(images) and len(twists) == len(images) - 1
    for p in poses:
        assert np.all(np.isfinite([p.x_m, p.y_m, p.theta_rad])) and np.all(np.isfinite(p.cov_xyt))
    for t in twists:
        assert np.all(np.isfinite([t.speed_mps, t.yaw_rate_radps])) and np.all(np.isfinite(t.cov))
    s = slam.summary()
    assert s["empty_images"] == 1
    # the empty, constant (no contrast) and single-cell images cannot be matched: counted, the
    # prediction kept (no motion: the pose stays at the origin)
    assert s["match_failures"] >= 3
    assert max(abs(p.x_m) + abs(p.y_m) for p in poses) < 0.5


def test_builder_on_silent_beams_and_a_single_beam_turn():
    empty = np.zeros(IMPALA.n_bins, np.float32)
    beams = [(1_000_000 * (k + 1), "beams", RadarBeam(2 * np.pi * (k + 0.5) / 360, 0, k, empty, empty, IMPALA))
             for k in range(360)]
    beams.append((400_000_000, "beams", RadarBeam(0.1, 1, 0, empty, empty, IMPALA)))  # a lone beam of turn 1
    images = CollectingSink("img")
    pano = PanoramicBuilder("pano", normalise="beam_median", range_max_m=30.0)
    run_components(ScriptedSource("src", beams), pano, images,
                   connections=["src.beams -> pano.beams", "pano.image -> img.x"])
    (img,) = images.values()
    assert not np.any(img.data) and np.all(np.isfinite(img.data))
    assert pano.summary()["dropped_turns"] == 1  # one beam is below min_turn_fraction


def test_bootstrap_on_silent_turns_starts_from_rest():
    """Twist connected, no odometry: the first turn waits for the second; two silent turns
    give no displacement peak, so the bootstrap speed is 0 (finite), never NaN."""
    empty = np.zeros(IMPALA.n_bins, np.float32)
    beams = [(1_000_000 * (k + 1), "beams", RadarBeam(2 * np.pi * ((k % 360) + 0.5) / 360, k // 360, k % 360,
                                                      empty, empty, IMPALA)) for k in range(720)]
    images = CollectingSink("img")
    pano = PanoramicBuilder("pano", range_max_m=30.0)
    run_components(ScriptedSource("src", beams, ports=["beams", "twist"]), pano, images,
                   connections=["src.beams -> pano.beams", "src.twist -> pano.twist", "pano.image -> img.x"])
    assert len(images.values()) == 2
    assert pano.summary()["motion"] == {"bootstrap": 2}
    assert pano._bootstrap_v == 0.0
