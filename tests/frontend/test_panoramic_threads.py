"""PanoramicBuilder's ``threads``: its grid loops shared by bands of rows give the same images,
bit for bit, with 1, 2 or 3 threads, on a Navtech's geometry with graphs/oxford.yaml's settings
(RADIATE) and on the IMPALA radar's with odometer, gyro and Doppler compensation (Beynes)."""

from __future__ import annotations

import numpy as np
import pytest

from impala_flow.msgs import Twist2D
from impala_flow.testing import CollectingSink, ScriptedSource, run_components
from impala_msgs import Speed, YawRate
from impala_radar.panoramic.component import PanoramicBuilder
from impala_radar.panoramic.core import BandPool, scan_to_grid
from impala_radar.simulator.core import simulate
from impala_radar.simulator.presets import IMPALA, NAVTECH
from impala_radar.simulator.spectra import RadarParams
from impala_radar.simulator.vehicle import Trajectory
from impala_radar.simulator.world import WorldBuilder

POINTS = np.array([[30.0, 20.0], [-25.0, -15.0], [5.0, 40.0], [40.0, -30.0]])
OXFORD = {"cell_m": 0.1, "range_max_m": 60.0, "range_min_m": 2.0, "reference": "middle", "normalise": "beam_median"}


def _beams(preset, duration_s: float, yaw_rate: float = 0.2):
    """A simulated drive at 5 m/s on a circle past four reflectors: the beams and the trajectory."""
    rng = np.random.default_rng(11)
    b = WorldBuilder(rng)
    b.points(POINTS, 1.3, 10.0, "point")
    r = 5.0 / yaw_rate
    a = np.linspace(-0.5, 1.0, 40)
    traj = Trajectory.from_waypoints(np.column_stack([r * np.sin(a), r * (1 - np.cos(a))]), 5.0,
                                     rest_at_ends=False, max_curvature_1pm=1.0 / (0.9 * r))
    ev = simulate(b.build(), traj, preset, rng, start_t_ns=traj.start_ns + 1_000_000_000,
                  duration_ns=round(duration_s * 1e9), params=RadarParams(thermal_noise=False))
    return [(t, "beams", beam) for t, port, beam in ev if port == "beams"], traj


def _images(samples, connections, threads: int, **params):
    """The images (time, cells) of one offline run, and the CPU seconds of the pool's workers."""
    pano = PanoramicBuilder("pano", threads=threads, **params)
    sink = CollectingSink("img")
    run_components(ScriptedSource("src", samples), pano, sink, connections=connections + ["pano.image -> img.x"])
    return [(s.timestamp, s.data.data) for s in sink.samples], pano._pool.cpu_s


def _same(a, b) -> bool:
    return len(a) == len(b) and all(ta == tb and np.array_equal(ga.view(np.int32), gb.view(np.int32))
                                    for (ta, ga), (tb, gb) in zip(a, b, strict=True))


def test_navtech_images_with_oxford_settings_are_the_same_bits_whatever_the_threads():
    beams, _ = _beams(NAVTECH, 0.75)
    samples = [(beams[0][0] - 1, "twist", Twist2D(5.0, 0.2))] + beams
    connections = ["src.beams -> pano.beams", "src.twist -> pano.twist"]
    one, cpu_one = _images(samples, connections, 1, bootstrap=False, **OXFORD)
    assert len(one) >= 2 and all(np.count_nonzero(g) > 0.5 * g.size for _, g in one)
    assert cpu_one == 0.0
    for threads in (2, 3):
        images, cpu = _images(samples, connections, threads, bootstrap=False, **OXFORD)
        assert _same(one, images)
        assert cpu > 0.0  # the pool's threads computed bands


def test_impala_images_with_odometry_and_doppler_are_the_same_bits_whatever_the_threads():
    beams, traj = _beams(IMPALA, 1.0)
    t0, t1 = beams[0][0], beams[-1][0]
    span = (t0 - 40_000_000, t1 + 40_000_000)
    odo = [(t, "odo", Speed(float(traj.velocity(t)[0]))) for t in range(*span, 20_000_000)]
    gyr = [(t, "gyro", YawRate(float(traj.velocity(t)[1]))) for t in range(*span, 10_000_000)]
    samples = sorted(beams + odo + gyr, key=lambda s: s[0])
    connections = ["src.beams -> pano.beams", "src.odo -> pano.odometer", "src.gyro -> pano.gyro"]
    one, _ = _images(samples, connections, 1, cell_m=0.2, ground_range=True)
    assert len(one) >= 1 and np.count_nonzero(one[0][1]) > 0.5 * one[0][1].size
    for threads in (2, 3):
        images, cpu = _images(samples, connections, threads, cell_m=0.2, ground_range=True)
        assert _same(one, images) and cpu > 0.0


@pytest.mark.parametrize("uniform", [True, False])
def test_grid_bands_cover_every_row_once(uniform):
    """With bands, every cell of the square is written (off the disk and blanked cells 0), as
    one thread writes it (scan_to_grid's grid is np.empty: a row no band wrote would differ),
    with a uniform azimuth table and with missing beams."""
    rng = np.random.default_rng(2)
    az = np.arange(0, 400) * 2 * np.pi / 400 if uniform else np.concatenate([np.arange(0, 150), np.arange(170, 400)]) \
        * 2 * np.pi / 400
    power = rng.exponential(1.0, (len(az), 200)).astype(np.float32)
    poses = np.column_stack([np.linspace(-1.2, 0.0, len(az)), np.linspace(-0.1, 0.0, len(az)),
                             np.linspace(-0.05, 0.0, len(az))])
    want, _ = scan_to_grid(power, az, poses, 0.2, 0.25, 35.0, 1.0, 0.05, 1.5)
    for threads in (2, 3, 4):
        pool = BandPool(threads)
        try:
            got, _ = scan_to_grid(power, az, poses, 0.2, 0.25, 35.0, 1.0, 0.05, 1.5, pool=pool)
        finally:
            pool.close()
        assert np.array_equal(got.view(np.int32), want.view(np.int32))


def test_beam_normalisation_by_bands_is_the_same_bits():
    """normalise_beams shared by bands of beams: each beam divided by its median (np.median), a
    blanked beam by its smallest positive power, an all-zero beam left at 0, as one thread does."""
    from impala_radar.panoramic.core import normalise_beams

    rng = np.random.default_rng(1)
    p = rng.exponential(1.0, (401, 576)).astype(np.float32)
    p[5] = 0.0
    p[7, :300] = 0.0
    floor = np.median(p, axis=1)
    floor[5], floor[7] = 1.0, p[7][p[7] > 0].min()  # the median of beam 7 is 0: its smallest positive power
    want = p / floor[:, None]
    for threads in (1, 2, 3, 4):
        pool = BandPool(threads)
        try:
            got = normalise_beams(p, pool)
        finally:
            pool.close()
        assert np.array_equal(got.view(np.int32), want.astype(np.float32).view(np.int32))
