"""The simulator's per-turn compiled passes (impala_radar.simulator.kernels: block_pairs,
pair_ranges / pair_power; synth_kernels: ramp_echoes, spread_fold, windowed_samples, bin_powers,
the exact mod 2 pi) give, bit for bit, what the formulations they replaced give: the per-block loop of
candidates, walls, discs and pairs, spectra.pair_echoes, and the numpy expressions of the
synthesizer written out below. So seeded missions did not change."""

from __future__ import annotations

import math

import numpy as np
import scipy.fft

from impala_msgs import SPEED_OF_LIGHT_MPS
from impala_radar.simulator import kernels, synth_kernels
from impala_radar.simulator.presets import preset
from impala_radar.simulator.spectra import Echoes, RadarParams, Synthesizer, pair_echoes
from impala_radar.simulator.world import World, disc_transmission

TWO_PI = 2.0 * math.pi


def _bits_equal(a, b) -> None:
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape
    np.testing.assert_array_equal(a.view(np.uint8), b.view(np.uint8))  # signed zeros and NaNs included


def test_mod_2pi_is_numpys_remainder_for_every_magnitude() -> None:
    rng = np.random.default_rng(11)
    k = np.arange(1.0, 200001.0)
    a = np.concatenate([rng.uniform(-1e5, 1e5, 200000), rng.uniform(-10, 10, 20000), rng.uniform(-1e12, 1e12, 20000),
                        k * TWO_PI, -k * TWO_PI, np.nextafter(k * TWO_PI, 0), np.nextafter(k * TWO_PI, np.inf),
                        [0.0, -0.0, 5e-324, -5e-324, 2.0**24 * TWO_PI, 1e300, -1e300, np.inf, -np.inf, np.nan]])
    with np.errstate(invalid="ignore"):
        want = a % TWO_PI
    _bits_equal(np.array([synth_kernels._mod_2pi(x) for x in a]), want)
    _bits_equal(synth_kernels.wrap_phase32(a), want.astype(np.float32))


def _echoes(rng, n: int, n_beams: int, max_range_m: float = 140.0) -> Echoes:
    return Echoes(np.sort(rng.integers(0, n_beams, n)), rng.uniform(0.5, max_range_m, n), rng.uniform(-30.0, 30.0, n),
                  10.0 ** rng.uniform(-16, -8, n), rng.uniform(0.0, TWO_PI, n))


def test_a_ramps_echoes_are_prepared_as_the_numpy_synthesizer_did() -> None:
    rng = np.random.default_rng(12)
    for name in ("impala", "navtech"):
        syn = Synthesizer(preset(name), RadarParams())
        config = syn.config
        c_range = 4.0 * config.bandwidth_hz * config.modulation_hz / SPEED_OF_LIGHT_MPS
        e = _echoes(rng, 30000, 40, 1.3 * (0.5 * syn.fs_hz / c_range + config.range_offset_m))
        f_r = c_range * (e.range_m - config.range_offset_m)
        f_d = 2.0 * config.f0_hz / SPEED_OF_LIGHT_MPS * e.radial_mps
        k = 4.0 * math.pi / syn.lambda_m
        half = 0.5 * syn.ramp_s * e.radial_mps
        for mode in ((0,) if syn.single_ramp else (1, 2)):
            f, ph = {0: (f_r + 2.0 * f_d, e.phase_rad + k * e.range_m),
                     1: (f_r + f_d, e.phase_rad + k * (e.range_m - half)),
                     2: (f_r - f_d, e.phase_rad + k * (e.range_m + half))}[mode]
            got_f, arg, base, ph32, amp32 = syn._prepare(e, mode)
            _bits_equal(got_f, f)
            _bits_equal(syn._beat_hz(e, mode), f)
            ok = np.abs(f) < 0.5 * syn.fs_hz
            assert 0 < ok.sum() < len(f)  # both sides of the band exercised
            x = synth_kernels.grid_positions(f[ok], syn.n_grid / syn.fs_hz, float(syn.n_grid))
            want_arg, want_base = synth_kernels.kernel_arguments(x, e.beam[ok], syn.n_grid + 5, syn._offsets,
                                                                 syn._u_scale, np.float32(2.3 * 6))
            _bits_equal(arg, want_arg)
            _bits_equal(base, want_base)
            _bits_equal(ph32, (ph[ok] % TWO_PI).astype(np.float32))
            _bits_equal(amp32, np.sqrt(2.0 * e.power_w[ok]).astype(np.float32))


def test_a_ramps_echoes_in_parts_are_prepared_as_their_concatenation() -> None:
    rng = np.random.default_rng(16)
    syn = Synthesizer(preset("impala"), RadarParams())
    e = _echoes(rng, 30000, 40)
    cuts = [0, 1, 7000, 7000, 21000, 30000]
    parts = [Echoes(*(getattr(e, f)[a:b] for f in ("beam", "range_m", "radial_mps", "power_w", "phase_rad")))
             for a, b in zip(cuts[:-1], cuts[1:], strict=True)]
    for mode in (1, 2):
        for got, want in zip(syn._prepare(parts, mode), syn._prepare(e, mode), strict=True):
            _bits_equal(got, want)


def test_spread_fold_is_the_bincount_grid_folded() -> None:
    rng = np.random.default_rng(13)
    n, n_beams, width, m_grid = 20000, 12, 6, 576
    row, o = m_grid + width - 1, width // 2 - 1
    beam = np.sort(rng.integers(0, n_beams, n))
    x = rng.uniform(0.0, m_grid, n)
    arg, base = synth_kernels.kernel_arguments(x, beam, row, (np.arange(width) - o).astype(np.float32),
                                         np.float32(2.0 / width), np.float32(2.3 * width))
    ker = np.exp(arg)
    amp, ph = rng.uniform(0, 1e-4, n).astype(np.float32), rng.uniform(0, TWO_PI, n).astype(np.float32)
    b_re, b_im = synth_kernels.spread(base, ker, amp * np.cos(ph), amp * np.sin(ph), n_beams * row)
    padded = (b_re + 1j * b_im).reshape(n_beams, row)
    want = padded[:, o:o + m_grid].copy()
    want[:, m_grid - o:] += padded[:, :o]
    want[:, : width - 1 - o] += padded[:, o + m_grid:]
    _bits_equal(synth_kernels.spread_fold(base, ker, amp, np.cos(ph), np.sin(ph), n_beams, m_grid, o), want)


def test_samples_and_bin_powers_are_the_numpy_expressions() -> None:
    rng = np.random.default_rng(14)
    config, params = preset("impala"), RadarParams()
    syn = Synthesizer(config, params)
    n_beams = 20
    z = rng.normal(size=(n_beams, syn.n_grid)) + 1j * rng.normal(size=(n_beams, syn.n_grid))
    noise = rng.standard_normal((n_beams, syn.n_samples))
    s = (z[:, syn._time_index] * syn._deapodize).real
    for nz in (noise, np.zeros((0, 0))):
        got = synth_kernels.windowed_samples(z, syn._time_index, syn._deapodize, nz, syn.window)
        _bits_equal(got, (s + nz if nz.size else s) * syn.window)
    x = scipy.fft.rfft(s * syn.window, n=syn.n_fft, axis=1)
    skirts = rng.uniform(0, 1e-15, (n_beams, config.n_bins)).astype(np.float32)
    xs = x[:, : config.n_bins] * syn._scale
    want = (0.5 * (xs.real**2 + xs.imag**2)).astype(np.float32)
    _bits_equal(synth_kernels.bin_powers(x, config.n_bins, syn._scale, np.zeros((0, 0), np.float32)), want)
    _bits_equal(synth_kernels.bin_powers(x, config.n_bins, syn._scale, skirts), want + skirts)
    _bits_equal(syn.power_spectrum(s), want)  # with the window, as the synthesizer's FFT


def _scene(rng, n: int):
    sx, sy = rng.uniform(-60, 60, n), rng.uniform(-60, 60, n)
    return sx, sy, rng.uniform(0, 4, n)


def test_block_pairs_are_the_per_block_loop() -> None:
    """Candidates by bearing, walls (ghosts see through), discs on the marked candidates, then the
    pairs in the pattern: the loop over blocks as it was written with the separate kernels."""
    rng = np.random.default_rng(15)
    n, n_beams, bb = 6000, 64, 8
    sx, sy, sz = _scene(rng, n)
    rx, ry = np.linspace(-1, 1, n_beams), np.linspace(0, 0.5, n_beams)
    beam_dir = np.mod(0.3 + TWO_PI / n_beams * (np.arange(n_beams) + 0.5), TWO_PI) - np.pi
    bearing = np.arctan2(sy, sx)
    rc = np.hypot(sx, sy)
    slack = rng.uniform(0.02, 0.1, n)
    near, far = np.nonzero(rc <= 5.0)[0], np.nonzero(rc > 5.0)[0]
    far = far[np.argsort(bearing[far], kind="stable")]
    far_slack = float(slack[far].max()) + 0.2
    tan_cut = np.tan(rng.uniform(0.01, 0.3, n))
    ghost = rng.uniform(size=n) < 0.1
    behind = rng.uniform(size=n) < 0.5
    a = rng.uniform(-40, 40, (10, 2))
    segs = np.column_stack([a, a + rng.uniform(-10, 10, (10, 2))])
    world = World(*(np.zeros(0),) * 4, np.zeros(0, np.uint8), np.zeros(0), segs)
    mids, halves = kernels.block_spans(beam_dir, bb)
    occ = [np.column_stack([rng.uniform(-30, 30, (k, 2)), rng.uniform(0.3, 2, k), np.zeros(k), rng.uniform(1, 5, k),
                            rng.choice([0.0, 0.06, 0.5], k)]) for k in rng.integers(0, 6, n_beams // bb)]
    occ_lo = np.concatenate([[0], np.cumsum([len(o) for o in occ])]).astype(np.intp)
    r2_max = 55.0**2
    want = []
    for b in range(n_beams // bb):
        sl = slice(b * bb, (b + 1) * bb)
        j = kernels.block_candidates(far, bearing[far], near, bearing, slack, mids[b], halves[b], far_slack)
        pos = np.array([rx[(sl.start + sl.stop - 1) // 2], ry[(sl.start + sl.stop - 1) // 2]])
        vis = world.visible(pos, sx[j], sy[j], segs) | ghost[j]
        if len(occ[b]) and behind[j].any():
            tr = np.ones(len(j))
            tr[behind[j]] = disc_transmission(pos, 1.3, sx[j][behind[j]], sy[j][behind[j]], sz[j][behind[j]], occ[b])
            vis = tr * vis
        bi, si, d = kernels.static_pairs(rx[sl], ry[sl], np.cos(beam_dir[sl]), np.sin(beam_dir[sl]), sx[j], sy[j],
                                         tan_cut[j], r2_max, vis > 0)
        shadow = vis[si] if vis.dtype != bool else np.ones(len(si))
        want.append((sl.start + bi, j[si], np.vstack([d, shadow])))
    for cap in (0, 10**6):  # buffers grown, or large enough
        beam, jj, d = kernels.block_pairs(
            0, n_beams // bb, bb, mids, halves, far, bearing[far], near, bearing, slack, far_slack, rx, ry,
            np.cos(beam_dir), np.sin(beam_dir), sx, sy, sz, tan_cut, r2_max, ghost, behind, True, segs,
            np.concatenate(occ), occ_lo, 1.3, 0.05, cap)
        _bits_equal(beam, np.concatenate([w[0] for w in want]))
        _bits_equal(jj, np.concatenate([w[1] for w in want]))
        _bits_equal(d, np.concatenate([w[2] for w in want], axis=1))
    assert 2000 < len(beam) and 0.0 < d[5].min() < 1.0  # pairs, some of them shadowed


def test_static_pair_physics_is_pair_echoes_then_the_culling() -> None:
    rng = np.random.default_rng(16)
    config, params = preset("impala"), RadarParams()
    syn = Synthesizer(config, params)
    n, ns, n_beams = 40000, 3000, 30
    sx, sy, sz = _scene(rng, ns)
    rcs, phase = 10.0 ** rng.uniform(-3, 1, ns), rng.uniform(0, TWO_PI, ns)
    area = np.where(rng.uniform(size=ns) < 0.5, 2.0, 0.0)
    beam, jj = np.sort(rng.integers(0, n_beams, n)), rng.integers(0, ns, n)
    rxy, rv = rng.uniform(-1, 1, (n_beams, 2)), rng.uniform(-5, 5, (n_beams, 2))
    dx, dy = sx[jj] - rxy[beam, 0], sy[jj] - rxy[beam, 1]
    c, s = np.cos(rng.uniform(-np.pi, np.pi, n_beams))[beam], np.sin(rng.uniform(-np.pi, np.pi, n_beams))[beam]
    d = np.vstack([dx, dy, dx * c + dy * s, dy * c - dx * s, dx * dx + dy * dy, rng.choice([1.0, 0.3, 0.0], n)])
    want = pair_echoes(beam, rv[beam], *d[:5], sz[jj], None, rcs[jj], phase[jj], area[jj], d[5], config, params)
    strong = want.power_w >= syn._cull_w
    assert 0 < strong.sum() < len(strong)
    from impala_radar.simulator.spectra import azimuth_pattern

    pattern = azimuth_pattern(config.beam_width_rad, params.sidelobe_db)
    lam = SPEED_OF_LIGHT_MPS / config.f0_hz
    r_h, dz, range_m, radial = kernels.pair_ranges(beam, jj, d, sz, config.height_m, rv[:, 0].copy(), rv[:, 1].copy())
    e_el = np.exp(kernels.elevation_exponent(np.arctan2(dz, r_h), params.elevation_beam_width_rad,
                                             -8.0 * math.log(2.0)))
    for cull in (True, False):
        got = kernels.pair_power(beam, jj, d, pattern.gain2(np.arctan2(d[3], d[2])), e_el, dz, range_m, range_m**4,
                                 radial, rcs, phase, area, True, math.sin(math.radians(params.grazing_ref_deg)),
                                 params.pt_g2_w(config) * lam**2 / (4.0 * math.pi) ** 3,
                                 10.0 ** (-params.pattern_cut_db / 10.0), cull, syn._cull_w)
        keep = strong if cull else np.ones(len(strong), bool)
        for g, w in zip(got, (want.beam, want.range_m, want.radial_mps, want.power_w, want.phase_rad), strict=True):
            _bits_equal(g, w[keep])


def test_a_turn_drawn_then_synthesized_is_spectra() -> None:
    """Synthesizer.spectra = synthesize(draw(...)): the draws first (in spectra's order), the
    synthesis (no randomness) after, with or without the down ramp on another thread."""
    from concurrent.futures import ThreadPoolExecutor

    config, params = preset("impala"), RadarParams()
    rng = np.random.default_rng(17)
    e = _echoes(rng, 20000, 30)
    want = Synthesizer(config, params).spectra(e, 30, np.random.default_rng(1))
    syn = Synthesizer(config, params)
    drawn = syn.draw(e, 30, np.random.default_rng(1))
    with ThreadPoolExecutor(1) as pool:
        for p in (None, pool):
            got = syn.synthesize(*drawn, 30, p)
            _bits_equal(got[0], want[0])
            _bits_equal(got[1], want[1])


def test_the_skirt_selection_is_the_numpy_expression() -> None:
    from impala_radar.simulator.receiver import skirt_echoes

    rng = np.random.default_rng(15)
    n = 50000
    power, range_m = 10.0 ** rng.uniform(-16, -6, n), rng.uniform(0.3, 200.0, n)
    ramp_s, enbw, noise, l_ref_dbc_hz, f_ref_hz = 1e-3, 1.5, 2e-15, -95.0, 1e5
    tau_s = 2.0 * range_m / 299_792_458.0
    flat = power * 10.0 ** (l_ref_dbc_hz / 10.0) * (2.0 * math.pi * f_ref_hz * tau_s) ** 2
    want = np.nonzero(flat * enbw / ramp_s >= 0.1 * noise)[0]
    assert 0 < len(want) < n  # both sides exercised
    _bits_equal(skirt_echoes(power, range_m, ramp_s, enbw, noise, l_ref_dbc_hz, f_ref_hz), want)
