"""FuzzyPairer: pairing quality on synthetic beams with known targets (simulator spectra)."""

import numpy as np

from impala_flow.testing import CollectingSink, ScriptedSource, run_components
from impala_msgs import SPEED_OF_LIGHT_MPS, RadarBeam
from impala_radar.pairer.component import FuzzyPairer
from impala_radar.pairer.core import (
    nearest_peak_pairs,
    pair_turn,
    radial_speed_from_beats_mps,
    range_from_beats_m,
    static_offset_bins,
    xcorr_speed_prior,
)
from impala_radar.pairer.fuzzy import pair_score
from impala_radar.peaks import cfar_factor
from impala_radar.simulator.presets import IMPALA

from ._scenes import beat_bins, score_pairs, target_beams

V_MPS = 5.0


def test_eq3_inverts_eq2():
    r, v = np.array([10.0, 50.0, 90.0]), np.array([-5.0, 0.0, 12.0])
    bu, bd = beat_bins(r, v)
    assert np.allclose(range_from_beats_m(bu * IMPALA.bin_hz, bd * IMPALA.bin_hz, IMPALA), r)
    assert np.allclose(radial_speed_from_beats_mps(bu * IMPALA.bin_hz, bd * IMPALA.bin_hz, IMPALA), v)
    # static target dead ahead at 5 m/s: up - down = 2 f_d = 4 f0 V / c
    assert np.isclose(static_offset_bins(0.0, V_MPS, IMPALA), 4 * 24e9 * -V_MPS / SPEED_OF_LIGHT_MPS / 360.0)


def test_cfar_factor_matches_closed_forms():
    # CA: Pfa = (1 + alpha / n)^-n
    a = cfar_factor(1e-4, 24, "ca")
    assert np.isclose((1 + a / 24) ** -24, 1e-4)
    # OS with k = n: Pfa = prod (n - i) / (n - i + alpha) -> check numerically
    a = cfar_factor(1e-3, 8, "os", k=8)
    i = np.arange(8)
    assert np.isclose(np.prod((8 - i) / (8 - i + a)), 1e-3)


def test_fuzzy_rules_order_candidates():
    near_same = pair_score(0.2, 0.5, 0.05, 0.95)
    far_same = pair_score(8.0, 0.5, 0.05, 0.95)
    near_diff_amp = pair_score(0.2, 9.0, 0.05, 0.95)
    assert near_same > far_same > 0.45 > near_diff_amp


def _evaluate(p, truth):
    m = score_pairs(p.up.beam[p.iu], p.up.bin[p.iu], p.down.bin[p.id], truth)
    return m


def test_pairs_95_percent_correct_with_two_movers_at_15_db():
    rng = np.random.default_rng(11)
    up, down, az, truth = target_beams(rng, n_beams=360, speed_mps=V_MPS, n_static=(1, 2),
                                       n_movers=(0, 2), snr_db=(15.0, 15.0))
    prior = xcorr_speed_prior(up, down, az, IMPALA)
    assert abs(prior - V_MPS) < 0.25  # the spectra alone give the ego-speed prior
    p = pair_turn(up, down, az, IMPALA, prior)
    m = _evaluate(p, truth)
    correct = (m >= 0).mean()
    found = len(set(m[m >= 0])) / len(truth["beam"])
    ghost_rate = (m < 0).mean()
    movers_found = truth["mover"][m[m >= 0]].sum() / truth["mover"].sum()
    print(f"\n15 dB, <= 2 movers/beam: {len(m)} pairs, correct {correct:.3f}, targets found {found:.3f} "
          f"(movers {movers_found:.3f}), ghost rate {ghost_rate:.3f} per pair, "
          f"{(m < 0).sum() / 360:.3f} per beam")
    assert correct >= 0.95
    # bound: the 5 % of wrong pairs the requirement allows, OS-CFAR noise peaks being
    # rejected by the amplitude rules (2 x 288 bins x 1e-4 = 0.06 noise peaks per beam)
    assert ghost_rate <= 0.05
    assert found >= 0.8  # at 15 dB (OS-CFAR Pd ~ 0.9 per ramp, squared: ~0.85)


def test_fuzzy_beats_nearest_peak_on_crowded_beams():
    rng = np.random.default_rng(12)
    up, down, az, truth = target_beams(rng, n_beams=180, speed_mps=V_MPS, n_static=(2, 3),
                                       n_movers=(1, 2), range_m=(20.0, 50.0), min_sep_m=2.5,
                                       snr_db=(15.0, 30.0))
    # the speed prior the component uses without an odometer: the up/down cross-correlation
    # of the turn itself, never the true speed
    prior = xcorr_speed_prior(up, down, az, IMPALA)
    assert abs(prior - V_MPS) < 1.0
    p = pair_turn(up, down, az, IMPALA, prior)
    m = _evaluate(p, truth)
    gate = abs(static_offset_bins(0.0, 30.0, IMPALA))
    iu, id_ = nearest_peak_pairs(p.up, p.down, gate)
    mn = score_pairs(p.up.beam[iu], p.up.bin[iu], p.down.bin[id_], truth)
    iu2, id2 = nearest_peak_pairs(p.up, p.down, gate, static_offset_bins(az, prior, IMPALA))
    mn2 = score_pairs(p.up.beam[iu2], p.up.bin[iu2], p.down.bin[id2], truth)
    fz, nv, nv2 = (m >= 0).mean(), (mn >= 0).mean(), (mn2 >= 0).mean()
    print(f"\ncrowded beams (3-5 targets in 30 m): fuzzy {fz:.3f} correct of {len(m)}, "
          f"nearest-peak {nv:.3f} of {len(mn)}, nearest-peak around the static offset {nv2:.3f}; "
          f"ghosts fuzzy {(m < 0).sum()}, naive {(mn < 0).sum()}")
    assert fz > nv + 0.05 and fz > nv2
    assert (m < 0).sum() < (mn < 0).sum()


def test_component_emits_one_batch_per_turn():
    rng = np.random.default_rng(13)
    up, down, az, truth = target_beams(rng, n_beams=360, speed_mps=V_MPS, n_static=(1, 1), n_movers=(0, 0),
                                       snr_db=(25.0, 25.0))
    t_ns = 1_000_000 + np.arange(360, dtype=np.int64) * 2_777_778
    samples = [(int(t_ns[i]), "beams", RadarBeam(float(az[i]), 0, i, up[i], down[i], IMPALA))
               for i in range(360)]
    sink = CollectingSink("sink")
    run_components(ScriptedSource("src", samples), FuzzyPairer("pairer"), sink,
                   connections=["src.beams -> pairer.beams", "pairer.detections -> sink.x"])
    assert sink.times() == [int(t_ns[-1])]
    d = sink.values()[0]
    assert len(d.range_m) >= 0.9 * 360
    assert np.array_equal(d.t_ns, t_ns[d.beam])
    # each detection near its beam's single target (eq. 3)
    k = np.searchsorted(truth["beam"], d.beam)
    assert np.median(np.abs(d.range_m - truth["range_m"][k])) < IMPALA.range_resolution_m / 4
    assert np.median(np.abs(d.radial_speed_mps - truth["radial_mps"][k])) < IMPALA.velocity_resolution_mps / 4



def test_os_cfar_is_the_rank_filter_of_the_training_cells():
    """The OS CFAR's level is the k-th smallest of the 2 x train cells around each bin: the
    value scipy.ndimage.rank_filter picks with that footprint (guard cells and the cell under
    test excluded, edges mirrored), ties included; find_os_peaks, which computes it only at the
    local maxima, finds the peaks find_peaks finds above that threshold, NaN spectra included."""
    from scipy import ndimage

    from impala_radar.peaks import cfar_threshold, find_os_peaks, find_peaks

    rng = np.random.default_rng(3)
    power = rng.exponential(1.0, (40, 300)).astype(np.float32)
    power[:, 100:140] = np.round(power[:, 100:140])  # ties
    power[:, 200:260:15] *= 300.0  # targets
    train, guard = 12, 4
    footprint = np.ones((1, 2 * (train + guard) + 1), bool)
    footprint[0, train:train + 2 * guard + 1] = False
    k = int(round(0.75 * 2 * train)) - 1
    padded = np.pad(power, ((0, 0), (guard + train, guard + train)), mode="symmetric")
    level = ndimage.rank_filter(padded, k, footprint=footprint, mode="constant")[:, guard + train:-(guard + train)]
    thr = cfar_threshold(power, 1e-3, train, guard, "os")
    assert np.array_equal(thr, cfar_factor(1e-3, 2 * train, "os") * level.astype(np.float64))
    want = find_peaks(power, thr, 5)
    assert len(want[0]) > 40
    got = find_os_peaks(power, 1e-3, train, guard, 5)
    assert all(np.array_equal(a, b) for a, b in zip(got, want, strict=True))
    power[3, 50] = np.nan
    got = find_os_peaks(power, 1e-3, train, guard, 5)
    want = find_peaks(power, cfar_threshold(power, 1e-3, train, guard, "os"), 5)
    assert all(np.array_equal(a, b) for a, b in zip(got, want, strict=True))


def test_xcorr_lag_terms_are_the_numpy_formula_bit_for_bit():
    """The compiled lag terms of the xcorr prior against the (speeds, beams) numpy formula,
    float32 and float64 correlations, lags of both signs and beyond a row's length."""
    from impala_radar.pairer._jit import lag_terms
    from impala_radar.pairer.core import static_offset_bins

    rng = np.random.default_rng(12)
    az = np.sort(rng.uniform(0.0, 2 * np.pi, 90))
    speeds = np.concatenate([np.arange(-20.0, 20.0 + 1e-9, 0.25), [0.0, 150.0, -400.0]])
    n = 72
    for dtype in (np.float32, np.float64):
        c = rng.normal(0.0, 1.0, (len(az), 2 * n)).astype(dtype)
        lag = static_offset_bins(az[None, :], speeds[:, None], IMPALA)
        lo = np.floor(lag)
        w = lag - lo
        i0 = lo.astype(np.int64) % (2 * n)
        i1 = (i0 + 1) % (2 * n)
        rows = np.arange(len(az))[None, :]
        want = (1 - w) * c[rows, i0] + w * c[rows, i1]
        got = np.empty_like(want)
        lag_terms(c, np.cos(az), speeds, 4.0 * IMPALA.f0_hz, SPEED_OF_LIGHT_MPS * IMPALA.bin_hz, got)
        assert np.array_equal(got.view(np.int64), want.view(np.int64))
