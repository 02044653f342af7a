"""Simulated spectra against seed 1's FMCW equations (2)-(4) and speckle statistics."""

import math

import numpy as np
import pytest

from impala_radar.simulator.core import beam_azimuths_rad, beam_times_ns, simulate
from impala_radar.simulator.presets import IMPALA, K2PI, preset
from impala_radar.simulator.spectra import (
    Echoes,
    RadarParams,
    Synthesizer,
    noise_power_per_bin_w,
    received_power_w,
)
from impala_radar.simulator.world import Mover, WorldBuilder

from ._sim_helpers import StraightLine, beat_hz, peak_bin, range_velocity


def test_presets_match_the_papers():
    assert IMPALA.range_resolution_m == pytest.approx(0.75, abs=0.005)  # eq. (4)
    assert IMPALA.velocity_resolution_mps == pytest.approx(2.25, abs=0.005)
    assert K2PI.range_resolution_m == pytest.approx(0.60, abs=0.005)
    for cfg in (IMPALA, K2PI):
        ramp_s = 1 / (2 * cfg.modulation_hz)
        assert cfg.bin_hz <= 1 / ramp_s + 1e-9  # zero-padded, never coarser than 1/T
        assert cfg.n_bins * cfg.range_per_bin_m > cfg.range_max_m
    with pytest.raises(KeyError, match="impala, k2pi, navtech"):
        preset("nope")


def test_gridding_matches_direct_summation():
    syn = Synthesizer(IMPALA, RadarParams(thermal_noise=False))
    rng = np.random.default_rng(3)
    n = 300
    f_hz = rng.uniform(-0.5, 0.5, n) * syn.fs_hz
    amp, phase = rng.uniform(0.01, 1.0, n), rng.uniform(0, 2 * np.pi, n)
    z = syn.signal(np.zeros(n, int), f_hz, amp, phase, 1)
    t_s = (np.arange(syn.n_samples) - syn.n_samples // 2) / syn.fs_hz
    direct = (amp * np.exp(1j * (2 * np.pi * f_hz * t_s[:, None] + phase))).sum(axis=1)
    err = syn.power_spectrum((z - direct[None]).real)
    assert 10 * np.log10(err.max() / (amp.max() ** 2 / 2)) < -100.0


def _single_point_world(xy, rcs=10.0):
    b = WorldBuilder(np.random.default_rng(0))
    b.points([xy], IMPALA.height_m, rcs, "point")
    return b.build()


@pytest.mark.parametrize("case", ["mover_approaching", "radar_moving"])
def test_point_target_beat_frequencies_and_eq3(case):
    cfg = IMPALA
    if case == "mover_approaching":  # static radar heading east, target north, V = -7 m/s
        traj = StraightLine(0.0, 0.0, 0.0, 0.0, 1.0)
        world = _single_point_world((500.0, 500.0), rcs=1e-12)
        mover = Mover(1, np.array([[0.0, 60.0], [0.0, 10.0]]), 7.0, 0,
                      np.array([[0.0, 0.0, cfg.height_m]]), np.array([10.0]), np.zeros(1))
        world.movers.append(mover)
        j = 89  # azimuth 89.5 deg
    else:  # radar driving east at 5 m/s toward a static point 40 m ahead (beam 0: 0.5 deg)
        traj = StraightLine(0.0, 0.0, 0.0, 5.0, 1.0)
        world = _single_point_world((40.0, 0.0))
        j = 0
    beams = [m for _, p, m in simulate(world, traj, cfg, np.random.default_rng(1)) if p == "beams"]
    beam = beams[j]
    t_ns = beam_times_ns(0, 0, cfg)[j]
    radar = traj.pose(t_ns)[:2]
    target = mover.state(t_ns)[0] if case == "mover_approaching" else np.array([40.0, 0.0])
    los = target - radar
    r_true = float(np.hypot(*los))
    vel = (mover.state(t_ns)[1] if case == "mover_approaching" else np.zeros(2)) \
        - traj.velocity(t_ns)[0] * np.array([1.0, 0.0])
    v_true = float(los @ vel / r_true)
    f_r, f_d = beat_hz(r_true, v_true, cfg)
    assert v_true < -4.0  # approaching: V < 0 (seed 1 §2.1)
    k_up, k_down = (f_r + f_d) / cfg.bin_hz, (f_r - f_d) / cfg.bin_hz
    lo = int(cfg.bin_of_range(cfg.range_min_m))  # the transmitter leakage lives below range_min
    assert abs(lo + int(np.argmax(beam.up[lo:])) - k_up) <= 1.0
    assert abs(lo + int(np.argmax(beam.down[lo:])) - k_down) <= 1.0
    f_up = peak_bin(beam.up, 5, cfg.n_bins - 1) * cfg.bin_hz
    f_down = peak_bin(beam.down, 5, cfg.n_bins - 1) * cfg.bin_hz
    r_est, v_est = range_velocity(f_up, f_down, cfg)
    assert abs(r_est - r_true) < cfg.range_resolution_m / 4
    assert abs(v_est - v_true) < cfg.velocity_resolution_mps / 4
    # radar equation: the peak power is the received power within the window's scalloping
    p_true = received_power_w(r_true, 10.0, 1.0, cfg, RadarParams())
    assert 10 * np.log10(beam.up.max() / p_true) == pytest.approx(0.0, abs=2.0)


def _two_target_mean_spectrum(separation_m, window, n_real=256):
    """Mean power spectrum of two equal targets (random phases), as the Rayleigh criterion."""
    cfg = IMPALA
    syn = Synthesizer(cfg, RadarParams(window=window, thermal_noise=False))
    r0 = 40 * cfg.range_per_bin_m  # on a bin
    rng = np.random.default_rng(5)
    beam = np.repeat(np.arange(n_real), 2)
    rng_m = np.tile([r0, r0 + separation_m], n_real)
    e = Echoes(beam, rng_m, np.zeros(2 * n_real), np.full(2 * n_real, 1e-12),
               rng.uniform(0, 2 * np.pi, 2 * n_real))
    up, _ = syn.spectra(e, n_real, rng)
    return up.mean(axis=0), int(round(r0 / cfg.range_per_bin_m))


def _peaks(spectrum, lo, hi):
    s = spectrum[lo:hi]
    return [lo + i for i in range(1, len(s) - 1) if s[i] > s[i - 1] and s[i] >= s[i + 1]]


def test_two_targets_rayleigh_resolution():
    d_r = IMPALA.range_resolution_m
    # unweighted spectrum (the premise of eq. 4): dR apart -> two peaks with a dip
    mean, k0 = _two_target_mean_spectrum(d_r, "rect")
    peaks = _peaks(mean, k0 - 1, k0 + 4)
    assert len(peaks) == 2
    assert mean[peaks[0]:peaks[1] + 1].min() < 0.9 * min(mean[peaks[0]], mean[peaks[1]])
    # closer than dR/2 -> one peak
    mean, k0 = _two_target_mean_spectrum(0.45 * d_r, "rect")
    assert len(_peaks(mean, k0 - 2, k0 + 4)) == 1
    # with the default Hann window the resolution is about 2 dR
    mean, k0 = _two_target_mean_spectrum(2 * d_r, "hann")
    assert len(_peaks(mean, k0 - 1, k0 + 6)) == 2
    mean, k0 = _two_target_mean_spectrum(d_r, "hann")
    assert len(_peaks(mean, k0 - 2, k0 + 5)) == 1


def test_homogeneous_clutter_is_speckled():
    cfg = IMPALA
    b = WorldBuilder(np.random.default_rng(11))
    b.clutter((-45.0, 10.0, 45.0, 45.0), 8.0, -20.0)
    world = b.build()
    traj = StraightLine(0.0, 0.0, 0.0, 0.0, 1.0)
    params = RadarParams(thermal_noise=False)
    beams = [m for _, p, m in simulate(world, traj, cfg, np.random.default_rng(2),
                                       params=params) if p == "beams"]
    up = np.array([m.up for m in beams[60:121]], float)  # 60..120 deg: inside the field
    k = np.arange(int(33 / cfg.range_per_bin_m), int(42 / cfg.range_per_bin_m))
    cells = up[:, k] / up[:, k].mean(axis=0)  # remove the range trend (R^-3)
    cv = cells.std() / cells.mean()
    assert 0.8 < cv < 1.2


def test_thermal_noise_floor():
    cfg = IMPALA
    world = _single_point_world((1000.0, 1000.0), rcs=1e-12)
    traj = StraightLine(0.0, 0.0, 0.0, 0.0, 0.2)
    up = np.array([m.up for _, p, m in simulate(world, traj, cfg, np.random.default_rng(4))
                   if p == "beams"])
    expected = 1.380649e-23 * 290 * 10 ** (10 / 10) * 1.5 * 2 * cfg.modulation_hz  # kTF ENBW/T
    assert noise_power_per_bin_w(cfg, RadarParams()) == pytest.approx(expected, rel=0.02)
    assert up[:, 10:-10].mean() == pytest.approx(expected, rel=0.05)


def test_beam_timing_and_azimuths():
    t = beam_times_ns(1_000, 2, IMPALA)
    assert t.dtype == np.int64 and np.all(np.diff(t) > 0)
    assert t[0] == 1_000 + round((720.5) * 1e9 / 360)
    az = beam_azimuths_rad(IMPALA)
    assert az[0] == pytest.approx(math.radians(0.5)) and az[-1] < 2 * np.pi
    assert np.allclose(np.diff(az), 2 * np.pi / 360)  # one degree per beam, counter-clockwise
    # a clockwise antenna starting at 90 deg: beam j at 90 - (j + 1/2) deg, wrapped to [0, 360)
    cw = beam_azimuths_rad(IMPALA, RadarParams(clockwise=True, start_azimuth_rad=math.radians(90.0)))
    assert np.allclose(np.degrees(cw), np.mod(90.0 - (np.arange(360) + 0.5), 360.0))
