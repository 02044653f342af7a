"""No warning, no NaN on degenerate inputs (issue 9 item 5): empty, constant, single-echo and
subnormal images through R-SLAM, silent beams through the panoramic builder. Every pose
emitted is finite; the conditions are counted in the components' summaries. (pytest turns
any RuntimeWarning into an error for the whole suite.)"""

import dataclasses
import math

import numpy as np
import pytest

from impala_eval.evaluator.component import TrajectoryEvaluator
from impala_eval.tracking.component import TrackingEvaluator
from impala_flow import Component, Input, Param
from impala_flow.msgs import Grid
from impala_flow.testing import CollectingSink, ScriptedSource, run_components
from impala_msgs import ObjectStates, RadarBeam
from impala_radar.ego_velocity.component import EgoVelocity
from impala_radar.extractor.component import PeakExtractor
from impala_radar.pairer.component import FuzzyPairer
from impala_radar.panoramic.component import PanoramicBuilder
from impala_radar.simulator.presets import IMPALA
from impala_slam.ekf_slam.component import EkfSlam
from impala_slam.fmt.component import FmtRegistration
from impala_slam.kissicp.component import KissIcp
from impala_slam.odometry.component import DistortionOdometry
from impala_slam.posegraph.component import PoseGraph
from impala_slam.rslam.component import RSlam
from impala_tracking.detector.component import MoverDetector
from impala_tracking.tracker.component import Tracker

from .beams import CASES, SPEED_MPS, YAW_RATE_RADPS, corrupt, navtech_beams, truth_poses

N = 201


def _grid(data):
    return Grid(np.asarray(data, np.float32), 0.2, -20.0, -20.0, "vehicle", None)


def _rslam(images):
    src = ScriptedSource("src", [(k * 1_000_000_000, "img", g) for k, g in enumerate(images)])
    poses, twists = CollectingSink("poses"), CollectingSink("twists")
    slam = RSlam("slam", range_max_m=20.0)
    summary = run_components(src, slam, poses, twists,
                             connections=["src.img -> slam.image", "slam.pose -> poses.x", "slam.twist -> twists.x"])
    return slam, poses.values(), twists.values(), summary


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
    slam, poses, twists, summary = _rslam(images)
    # the image with a NaN cell never reaches R-SLAM: dropped where it enters, counted (issue 24)
    assert summary.invalid() == {"slam.image": {"non-finite data": 1}}
    assert len(poses) == len(images) - 1 and len(twists) == len(images) - 2
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


# --- every SLAM / odometry / tracking chain on degenerate beams (issue 24 items 9 and 10) ------
# Each chain is wired as its graph wires it (graphs/odometry_navtech, fmt_ekf_navtech, oxford,
# kiss_icp_navtech, datmo); the beams are synthetic Navtech-like turns among point reflectors
# (tests/slam/beams.py) or their degenerate versions. None may crash, emit a non-finite value
# or stay silent: non-finite beams are dropped where they enter and counted; a turn a
# component can do nothing with (all-zero, one beam) is counted in its summary.


class RawSink(Component):
    """Keeps every sample on the inputs named in ``ports``, unchecked (validate=False): the
    test looks at what the components emitted, invalid or not."""

    ports = Param(list, default=["x"])

    @classmethod
    def declare_ports(cls, params):
        return {p: Input(object, validate=False) for p in params["ports"]}, {}

    def start(self):
        self.got = {p: [] for p in self.inputs}

    def process(self, t):
        self.got[self.trigger].append(self.inputs[self.trigger].take())


#: fields where NaN is the documented "not measured" (a power-only radar's radial speed and score)
_NAN_MEANS_UNKNOWN = {"radial_speed_mps", "score", "std_mps"}


def _non_finite(obj, path="") -> list[str]:
    """Paths of the non-finite numbers inside an emitted value (dataclasses walked by hand)."""
    bad = []
    if isinstance(obj, (float, np.floating)):
        return [] if math.isfinite(obj) else [path]
    if isinstance(obj, np.ndarray):
        return [path] if obj.dtype.kind in "fc" and not np.all(np.isfinite(obj)) else []
    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            v = getattr(obj, f.name)
            if f.name in _NAN_MEANS_UNKNOWN:
                v = np.nan_to_num(np.asarray(v, float), nan=0.0, posinf=np.inf, neginf=-np.inf)
            bad += _non_finite(v, f"{path}.{f.name}")
    return bad


def _odometry():
    return ([DistortionOdometry("odometry", map_period_s=1e6), TrajectoryEvaluator("eval", title="odometry")],
            ["src.beams -> odometry.beams", "odometry.pose -> eval.estimate", "src.truth -> eval.truth"],
            ["odometry.pose", "odometry.twist", "odometry.degraded", "odometry.map"], ["odometry.beams"])


def _fmt_ekf():
    fmt = dict(cell_m=0.2, size=256, range_min_m=2.5, range_max_m=25.0, taper_m=5.0)
    return ([DistortionOdometry("odometry", map_period_s=1e6),
             PanoramicBuilder("panoramic", cell_m=0.2, range_max_m=40.0, range_min_m=2.0, reference="middle",
                              normalise="beam_median"),
             FmtRegistration("fmt", **fmt), EkfSlam("ekf", **fmt, trajectory_period_s=0.25, map_period_s=0.5),
             PoseGraph("posegraph", solver="isam2", trajectory_period_s=0.25)],
            ["src.beams -> odometry.beams", "src.beams -> panoramic.beams", "odometry.twist -> panoramic.twist",
             "panoramic.image -> fmt.image", "panoramic.image -> ekf.image", "fmt.transform -> ekf.registration",
             "odometry.pose -> ekf.odometry", "ekf.constraints -> posegraph.constraints"],
            ["ekf.pose", "ekf.trajectory", "ekf.map", "ekf.constraints", "fmt.transform", "fmt.pose",
             "posegraph.trajectory"],
            ["odometry.beams", "panoramic.beams"])


def _rslam_chain():
    return ([PanoramicBuilder("panoramic", cell_m=0.2, range_max_m=40.0), RSlam("slam", range_max_m=40.0,
                                                                                  map_period_s=0.5)],
            ["src.beams -> panoramic.beams", "panoramic.image -> slam.image"],
            ["slam.pose", "slam.twist", "slam.map", "slam.prediction"], ["panoramic.beams"])


def _kissicp():
    return ([PeakExtractor("points", k=24, range_min_m=2.5), KissIcp("kissicp", max_range_m=40.0)],
            ["src.beams -> points.beams", "points.detections -> kissicp.detections"],
            ["points.detections", "kissicp.pose", "kissicp.twist"], ["points.beams"])


def _datmo():
    return ([FuzzyPairer("pairer", cfar="os", pfa=5e-3), EgoVelocity("ego"), MoverDetector("detector"),
             Tracker("tracker"), TrackingEvaluator("eval")],
            ["src.beams -> pairer.beams", "pairer.detections -> ego.detections",
             "pairer.detections -> detector.detections", "ego.speed -> detector.speed",
             "detector.movers -> tracker.detections", "tracker.tracks -> eval.tracks",
             "tracker.existence -> eval.existence", "src.truth -> eval.truth"],
            ["pairer.detections", "ego.speed", "detector.movers", "tracker.tracks", "tracker.existence"],
            ["pairer.beams"])


CHAINS = {"odometry": _odometry, "fmt_ekf": _fmt_ekf, "rslam": _rslam_chain, "kissicp": _kissicp, "datmo": _datmo}


@pytest.fixture(scope="module")
def clean_beams():
    return navtech_beams(turns=5)


def _counters(summary, name):
    return summary.extra.get(name, {})


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("chain", sorted(CHAINS))
def test_chains_on_degenerate_beams_never_crash_never_emit_non_finite_and_say_so(chain, case, clean_beams):
    beams = corrupt(clean_beams, case)
    n_bad = sum(not np.all(np.isfinite(b.up)) for _, _, b in beams)  # counted here, independently
    comps, conns, outs, entries = CHAINS[chain]()
    script = list(beams)
    if chain == "datmo":  # no mover: the truth is empty, in the tracker's frame
        script += [(t, "truth", ObjectStates(np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros((0, 2)), frame="radar"))
                   for t in range(1_000_000_000, beams[-1][0], 100_000_000)]
    if chain == "odometry":
        script += truth_poses()
    script.sort(key=lambda s: s[0])
    sink = RawSink("sink", ports=[o.replace(".", "_") for o in outs])
    summary = run_components(ScriptedSource("src", script, ports=["beams", "truth"]), *comps, sink,
                             connections=conns + [f"{o} -> sink.{o.replace('.', '_')}" for o in outs])
    assert summary.error is None
    # nothing non-finite comes out of any component
    emitted = {port: vals for port, vals in sink.got.items() if vals}
    bad = [(port, where) for port, vals in emitted.items() for v in vals for where in _non_finite(v)]
    assert bad == []
    # ... and nothing invalid travelled between the components either
    assert set(summary.invalid()) <= set(entries)
    # the non-finite beams were dropped where they entered, each counted
    for entry in entries:
        assert summary.inputs[entry]["invalid"] == n_bad
    if case in ("nan", "inf"):  # nothing reached the components: nothing came out
        assert n_bad == len(beams) and not emitted
        if chain == "odometry":
            assert _counters(summary, "eval")["not_scored"].startswith("not enough poses (estimate 0")
        return
    if case in ("nan10", "inf10"):
        assert 0.05 * len(beams) < n_bad < 0.15 * len(beams)
    # not silent: a turn a component can do nothing with is counted in its summary
    if case == "zero":
        turns = len({b.turn for _, _, b in beams})
        # the odometry's first turn is its reference (no estimate asked of it)
        name, counter, n = {"odometry": ("odometry", "degraded_turns", turns - 1),
                            "fmt_ekf": ("ekf", "empty_images", turns), "rslam": ("slam", "empty_images", turns),
                            "kissicp": ("kissicp", "skipped_turns", turns),
                            "datmo": ("pairer", "detections", 0)}[chain]
        assert _counters(summary, name)[counter] == n
    if case in ("single", "nan10", "inf10"):  # turns short of beams: counted (used as partial, or dropped)
        c = _counters(summary, entries[-1].split(".")[0])
        assert c.get("partial_turns", 0) + c.get("dropped_turns", 0) >= (4 if case == "single" else 1)
    if chain == "odometry":
        scored = _counters(summary, "eval")
        if case in ("clean", "nan10", "inf10"):  # against the unicycle the beams were made from
            twists = sink.got["odometry_twist"]
            assert twists and all(abs(t.speed_mps - SPEED_MPS) < 0.1 for t in twists)
            assert all(abs(t.yaw_rate_radps - YAW_RATE_RADPS) < 0.01 for t in twists)
            assert scored["ate_rmse_m"] < 0.1
        else:  # fewer than two poses: the evaluator says why it scored nothing
            assert scored["not_scored"].startswith("not enough poses")
