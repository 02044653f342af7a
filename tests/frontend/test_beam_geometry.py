"""radar.PanoramicBuilder on any beam geometry: rotation sense, beams per turn, missing beams,
partial turns, a turn that wraps through azimuth 0 (issue 9 item 1).

Every case runs the simulator's beams through the component a user runs; the references
are the simulator's truth (where each point target is) and the same scene acquired the
other way (the image must not depend on the order the antenna swept it in).
"""

import dataclasses
import math

import numpy as np
import pytest

from impala_flow.msgs import Grid
from impala_flow.testing import CollectingSink, ScriptedSource, run_components
from impala_msgs import Speed, YawRate
from impala_radar.panoramic.component import PanoramicBuilder
from impala_radar.panoramic.core import relative_to
from impala_radar.simulator.core import simulate
from impala_radar.simulator.presets import IMPALA, K2PI
from impala_radar.simulator.spectra import RadarParams
from impala_radar.simulator.vehicle import Trajectory
from impala_radar.simulator.world import WorldBuilder

CELL_M = 0.2
POINTS = np.array([[30.0, 20.0], [-25.0, -15.0], [5.0, 40.0], [30.0, -28.0], [-35.0, 25.0]])
# a 400-beam, 4 Hz radar (the Navtech's turn: one modulation period per beam, 1600 Hz) with
# the IMPALA's bandwidth and range bins
FOUR_HUNDRED = dataclasses.replace(IMPALA, name="400-beams", beams_per_turn=400, rotation_hz=4.0,
                                   modulation_hz=1600.0, bin_hz=IMPALA.bin_hz * 1600.0 / IMPALA.modulation_hz)


def _beams(config=IMPALA, clockwise=False, start_deg=0.0, speed_mps=0.0, turns=1.0):
    """Simulated beams of ``turns`` antenna turns over the point world (no thermal noise)."""
    rng = np.random.default_rng(5)
    b = WorldBuilder(rng)
    b.points(POINTS, config.height_m, 10.0, "point")
    if speed_mps:
        traj = Trajectory.from_waypoints(np.array([[-20.0, 0.0], [300.0, 0.0]]), speed_mps, rest_at_ends=False)
        start = traj.start_ns + 1_000_000_000
    else:
        traj = Trajectory.stationary(0.0, 0.0, 0.0, 10.0)
        start = traj.start_ns
    params = RadarParams(thermal_noise=False, clockwise=clockwise, start_azimuth_rad=math.radians(start_deg))
    duration = int(round(turns * 1e9 / config.rotation_hz))
    ev = simulate(b.build(), traj, config, rng, start_t_ns=start, duration_ns=duration, params=params)
    return traj, [(t, bm) for t, port, bm in ev if port == "beams"]


def _images(beams, traj=None, **params):
    """Run the builder (odometer + gyro from the truth when ``traj``); its images and summary."""
    samples = [(t, "beams", b) for t, b in beams]
    conns = ["src.beams -> pano.beams", "pano.image -> img.x"]
    if traj is not None:
        t0, t1 = beams[0][0] - 100_000_000, beams[-1][0] + 100_000_000
        samples += [(t, "odo", Speed(float(traj.velocity(t)[0]))) for t in range(t0, t1, 10_000_000)]
        samples += [(t, "gyro", YawRate(float(traj.velocity(t)[1]))) for t in range(t0, t1, 10_000_000)]
        conns += ["src.odo -> pano.odometer", "src.gyro -> pano.gyro"]
    samples.sort(key=lambda s: s[0])
    images = CollectingSink("img")
    pano = PanoramicBuilder("pano", cell_m=CELL_M, range_max_m=60.0, **params)
    run_components(ScriptedSource("src", samples), pano, images, connections=conns)
    return images.samples, pano.summary()


def _peak_error_cells(grid: Grid, truth_xy: np.ndarray, half: int = 25) -> np.ndarray:
    """Distance (cells) from each true point to the intensity centroid of its echo."""
    out = []
    for tx, ty in truth_xy:
        j, i = int(round((tx - grid.origin_x_m) / CELL_M)), int(round((ty - grid.origin_y_m) / CELL_M))
        sub = np.asarray(grid.data[i - half:i + half + 1, j - half:j + half + 1], float)
        w = np.where(sub >= 0.5 * sub.max(), sub, 0.0)
        yy, xx = np.mgrid[-half:half + 1, -half:half + 1]
        out.append(math.hypot((w * xx).sum() / w.sum(), (w * yy).sum() / w.sum()))
    return np.array(out)


def _truth_in_vehicle_frame(traj, t_ns: int) -> np.ndarray:
    return relative_to(np.column_stack([POINTS, np.zeros(len(POINTS))]), traj.pose(np.array([t_ns]))[0])[:, :2]


def _relative_difference(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(np.abs(a).max(), 1e-30))


def test_both_rotation_senses_give_the_same_image_of_a_static_scene():
    _, ccw = _beams(clockwise=False)
    _, cw = _beams(clockwise=True)
    assert np.all(np.diff(np.unwrap([b.azimuth_rad for _, b in cw])) < 0)  # really clockwise
    (a,), _ = _images(ccw)
    (b,), _ = _images(cw)
    # same beams at the same azimuths, swept the other way: the same polar samples
    assert _relative_difference(a.data.data, b.data.data) < 1e-4


def test_both_rotation_senses_place_targets_where_they_are_while_driving():
    """At 10 m/s a 1 s turn smears a target by up to 50 cells; motion-corrected, the two
    sweeps of the same scene agree with the truth within the polar sampling (2 cells) and
    with each other."""
    found = []
    for clockwise in (False, True):
        traj, beams = _beams(clockwise=clockwise, speed_mps=10.0)
        (img,), _ = _images(beams, traj)
        err = _peak_error_cells(img.data, _truth_in_vehicle_frame(traj, img.timestamp))
        assert err.max() <= 2.0, (clockwise, err)
        found.append(img)
    (img,), _ = _images(_beams(speed_mps=10.0)[1])  # the uncorrected image is far off
    traj = _beams(speed_mps=10.0)[0]
    assert _peak_error_cells(img.data, _truth_in_vehicle_frame(traj, img.timestamp), half=60).max() > 10.0


@pytest.mark.parametrize("config", [IMPALA, K2PI, FOUR_HUNDRED], ids=lambda c: f"{c.name}")
def test_any_number_of_beams_per_turn(config):
    traj, beams = _beams(config=config, clockwise=config is FOUR_HUNDRED, speed_mps=5.0)
    (img,), summary = _images(beams, traj)
    assert len(beams) == config.beams_per_turn and summary["turns"] == 1
    assert _peak_error_cells(img.data, _truth_in_vehicle_frame(traj, img.timestamp)).max() <= 2.0


def test_a_turn_that_wraps_through_azimuth_zero():
    _, ref = _beams()
    _, wrapped = _beams(start_deg=137.0)  # the turn starts at 137 deg and crosses 0 halfway
    az = np.array([b.azimuth_rad for _, b in wrapped])
    assert az[0] > 2.0 and az.min() < 0.1 and az.max() > 6.2
    (a,), _ = _images(ref)
    (b,), _ = _images(wrapped)
    # the beams now sit 137 deg = 152.2 steps further: half a step of azimuth difference at
    # most, i.e. bilinear interpolation error only: the images differ by far less than the
    # echoes (compare with a one-beam rotation: the difference would be of the echoes' size)
    diff = np.abs(a.data.data - b.data.data).sum() / np.abs(a.data.data).sum()
    assert diff < 0.5
    assert _peak_error_cells(b.data, POINTS).max() <= 1.5


def test_a_missing_beam_is_interpolated_and_a_lost_sector_is_left_unobserved():
    _, beams = _beams()
    (full,), _ = _images(beams)
    # one beam lost in the middle of a target's echo: the neighbours (1 deg away, within the
    # 4 deg beam) fill it
    az = np.array([b.azimuth_rad for _, b in beams])
    k = int(np.argmin(np.abs(az - math.atan2(20.0, 30.0))))
    (one,), _ = _images(beams[:k] + beams[k + 1:])
    assert _peak_error_cells(one.data, POINTS).max() <= 1.0
    assert np.abs(one.data.data - full.data.data).sum() < 0.1 * np.abs(full.data.data).sum()
    # a 30-degree sector lost (beams 200..229): nothing there, everything else unchanged
    (gap,), _ = _images(beams[:200] + beams[230:])
    x, y = np.meshgrid(gap.data.origin_x_m + CELL_M * np.arange(gap.data.data.shape[1]),
                       gap.data.origin_y_m + CELL_M * np.arange(gap.data.data.shape[0]))
    bearing = np.degrees(np.mod(np.arctan2(y, x), 2 * np.pi))
    inside = (bearing > 202) & (bearing < 228) & (np.hypot(x, y) > 1.0)
    outside = (bearing < 198) | (bearing > 232)
    assert not np.any(gap.data.data[inside])
    assert _relative_difference(gap.data.data * outside, full.data.data * outside) < 1e-4


def test_partial_first_and_last_turns():
    """A recording that starts 100 beams into a turn and stops 120 beams into the third:
    the partial first turn is imaged over the bearings it swept and nothing else; the last
    third of a turn is below ``min_turn_fraction`` (counted, not imaged) unless allowed."""
    traj, more = _beams(speed_mps=5.0, turns=3.0)
    cut = more[100:360 * 2 + 120]
    images, summary = _images(cut, traj)
    assert summary["turns"] == 2 and summary["partial_turns"] == 1 and summary["dropped_turns"] == 1
    assert [s.timestamp for s in images] == [cut[259][0], cut[619][0]]  # each turn's last beam
    first = images[0]
    truth = _truth_in_vehicle_frame(traj, first.timestamp)
    bearing = np.degrees(np.mod(np.arctan2(truth[:, 1], truth[:, 0]), 2 * np.pi))
    seen = (bearing > 104.0) & (bearing < 356.0)  # swept from 100.5 deg (the vehicle turns not)
    assert seen.sum() >= 2 and (~seen).sum() >= 1
    assert _peak_error_cells(first.data, truth[seen]).max() <= 2.0
    for tx, ty in truth[~seen]:  # never swept: not observed at all
        j = int(round((tx - first.data.origin_x_m) / CELL_M))
        i = int(round((ty - first.data.origin_y_m) / CELL_M))
        assert not np.any(first.data.data[i - 10:i + 11, j - 10:j + 11])
    images, summary = _images(cut, traj, min_turn_fraction=0.3)
    assert summary["turns"] == 3 and summary["partial_turns"] == 2 and "dropped_turns" not in summary


def _pairs(beams):
    from impala_radar.pairer.component import FuzzyPairer

    src = ScriptedSource("src", [(t, "beams", b) for t, b in beams])
    dets = CollectingSink("dets")
    pairer = FuzzyPairer("pairer")
    run_components(src, pairer, dets, connections=["src.beams -> pairer.beams", "pairer.detections -> dets.x"])
    return dets.values(), pairer.summary()


def test_pairer_sees_the_same_targets_either_way_and_keeps_a_partial_last_turn():
    found = {}
    for clockwise in (False, True):
        _, beams = _beams(clockwise=clockwise, turns=1.5)
        batches, summary = _pairs(beams)
        assert len(batches) == 2 and summary["partial_turns"] == 1
        d = batches[0]
        # the strongest detection near each target: (azimuth deg, range m)
        truth_az = np.degrees(np.mod(np.arctan2(POINTS[:, 1], POINTS[:, 0]), 2 * np.pi))
        truth_r = np.hypot(*POINTS.T)  # the points are at the radar's height
        az = np.degrees(np.mod(d.azimuth_rad, 2 * np.pi))
        picks = []
        for ta, tr in zip(truth_az, truth_r, strict=True):
            near = np.flatnonzero((np.abs(az - ta) < 3.0) & (np.abs(d.range_m - tr) < 1.0))
            assert near.size, (clockwise, ta, tr)
            k = near[np.argmax(d.amplitude[near])]
            picks.append((az[k], d.range_m[k]))
            assert abs(az[k] - ta) <= 1.0 and abs(d.range_m[k] - tr) <= IMPALA.range_resolution_m / 2
        found[clockwise] = np.array(picks)
        # the half turn: only what its 180 beams swept (counter-clockwise 0-180 deg, clockwise 180-360)
        half = batches[1]
        az = np.degrees(np.mod(half.azimuth_rad, 2 * np.pi))
        assert len(half.range_m) > 0 and np.all((az < 181) if not clockwise else (az > 179))
    assert np.allclose(found[False], found[True], atol=1e-6)  # the same beams, the same peaks
