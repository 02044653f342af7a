"""radar.PeakExtractor: known reflectors recovered within a bin, each with its beam's time; the
CA-CFAR's false alarms on noise at the rate its formula promises."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impala_flow.testing import CollectingSink, ScriptedSource, run_components
from impala_msgs import RadarBeam, RadarDetections
from impala_radar.datasets.common import navtech_config
from impala_radar.extractor.component import PeakExtractor

CONFIG = navtech_config("test-navtech", 576, 0.17361, range_offset_m=0.5 * 0.17361, beams_per_turn=400,
                        rotation_hz=4.0)
BEAM_NS = int(1e9 / (CONFIG.rotation_hz * CONFIG.beams_per_turn))


def turn_of(power: np.ndarray, turn: int = 0, t0_ns: int = 1_000_000_000) -> list[tuple[int, str, RadarBeam]]:
    """One turn of beams (counter-clockwise from azimuth 0) carrying ``power`` rows."""
    n = len(power)
    az = 2.0 * np.pi * np.arange(n) / n
    return [(t0_ns + i * BEAM_NS, "out", RadarBeam(float(az[i]), turn, i, power[i].astype(np.float32),
                                                    np.zeros(0, np.float32), CONFIG)) for i in range(n)]


def extract(samples, **params) -> list[RadarDetections]:
    sink = CollectingSink("sink")
    run_components(ScriptedSource("src", samples), PeakExtractor("points", **params), sink,
                   connections=["src.out -> points.beams", "points.detections -> sink.x"])
    return sink.values()


def test_known_reflectors_recovered_within_a_bin_with_their_beams_time():
    rng = np.random.default_rng(3)
    n_beams, n_bins = CONFIG.beams_per_turn, CONFIG.n_bins
    power = rng.exponential(1.0, (n_beams, n_bins))
    # 60 reflectors at known positions (metres, vehicle frame), 25-35 dB above the noise, each
    # spread over 3 bins as a windowed FFT would (the peak bin strongest)
    r_true = rng.uniform(4.0, 95.0, 60)
    a_true = rng.uniform(-math.pi, math.pi, 60)
    xy_true = np.column_stack([r_true * np.cos(a_true), r_true * np.sin(a_true)])
    beam = np.rint(np.mod(a_true, 2 * np.pi) / (2 * np.pi) * n_beams).astype(int) % n_beams
    k_bin = np.rint(CONFIG.bin_of_range(r_true)).astype(int)
    amp = 10.0 ** (rng.uniform(25.0, 35.0, 60) / 10.0)
    for d, f in ((-1, 0.3), (0, 1.0), (1, 0.3)):
        power[beam, k_bin + d] += f * amp
    det, = extract(turn_of(power), k=3, snr_db=15.0, separation_m=1.0, range_min_m=2.5)
    xy = np.column_stack([det.range_m * np.cos(det.azimuth_rad), det.range_m * np.sin(det.azimuth_rad)])
    # every reflector found: the nearest detection within one range bin along its beam and in its beam
    dist = np.hypot(*(xy[:, None, :] - xy_true[None, :, :]).transpose(2, 0, 1))
    nearest = dist.argmin(0)
    assert np.all(np.abs(det.range_m[nearest] - r_true) <= CONFIG.range_per_bin_m)
    spacing = 2 * math.pi / n_beams
    assert np.all(np.abs(np.angle(np.exp(1j * (det.azimuth_rad[nearest] - a_true)))) <= 0.5 * spacing + 1e-9)
    # and nothing else: noise 15 dB over its median (exp(-10^1.5 ln 2) per cell) gives no false point
    assert len(det.range_m) == 60
    # each point with its beam's time and index
    assert np.array_equal(det.t_ns, 1_000_000_000 + det.beam * BEAM_NS)
    assert np.allclose(det.azimuth_rad, 2 * np.pi * det.beam / n_beams)


def test_at_most_k_per_beam_the_strongest():
    power = np.ones((CONFIG.beams_per_turn, CONFIG.n_bins))
    power[:, 100:110] = 1000.0 + np.arange(10)  # ten strong bins in every beam, increasing
    det, = extract(turn_of(power), k=4, snr_db=10.0)
    assert len(det.range_m) == 4 * CONFIG.beams_per_turn
    assert np.allclose(np.unique(det.range_m), CONFIG.range_of_bin_m(np.arange(106, 110)))


@pytest.mark.parametrize("pfa", [1e-2, 1e-3])
def test_ca_cfar_false_alarm_rate_on_noise_matches_its_formula(pfa):
    """Exponential noise power (square-law detector): a CA-CFAR with the factor
    alpha = n (pfa^(-1/n) - 1) exceeds it in a fraction pfa of the cells (Rohling 1983)."""
    rng = np.random.default_rng(11)
    turns = 4
    power = rng.exponential(2.5, (turns * CONFIG.beams_per_turn, CONFIG.n_bins))
    samples = []
    for k in range(turns):
        samples += turn_of(power[k * 400:(k + 1) * 400], turn=k, t0_ns=1_000_000_000 + k * 400 * BEAM_NS)
    train, guard = 16, 2
    dets = extract(samples, method="cfar", pfa=pfa, train=train, guard=guard, k=CONFIG.n_bins, range_min_m=0.0)
    assert len(dets) == turns
    margin = train + guard  # cells whose training window reaches past the ends are mirrored: left out
    bins = np.concatenate([np.rint(CONFIG.bin_of_range(d.range_m)) for d in dets])
    inner = (bins >= margin) & (bins < CONFIG.n_bins - margin)
    cells = turns * CONFIG.beams_per_turn * (CONFIG.n_bins - 2 * margin)
    expected = pfa * cells
    assert abs(inner.sum() - expected) < 4.0 * math.sqrt(expected)  # binomial, 4 sigma
