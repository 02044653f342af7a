"""Synthetic beams with known targets, through the simulator's spectrum synthesiser."""

from __future__ import annotations

import numpy as np

from impala_msgs import SPEED_OF_LIGHT_MPS
from impala_radar.simulator.presets import IMPALA
from impala_radar.simulator.spectra import Echoes, RadarParams, Synthesizer, noise_power_per_bin_w


def beat_bins(range_m, radial_mps, config=IMPALA):
    """Analytic (up, down) beat positions in bins, eq. (2): f_r +- f_d."""
    f_r = 4.0 * config.bandwidth_hz * config.modulation_hz * np.asarray(range_m) / SPEED_OF_LIGHT_MPS
    f_d = 2.0 * config.f0_hz * np.asarray(radial_mps) / SPEED_OF_LIGHT_MPS
    return (f_r + f_d) / config.bin_hz, (f_r - f_d) / config.bin_hz


def target_beams(rng, n_beams=360, speed_mps=5.0, n_static=(1, 2), n_movers=(0, 2),
                 snr_db=(15.0, 15.0), range_m=(6.0, 90.0), min_sep_m=2.0, mover_mps=(2.0, 15.0),
                 config=IMPALA):
    """(up, down, azimuth_rad, truth) for ``n_beams`` beams of one turn with known targets.

    Per beam: a random number of static targets (radial speed -v cos(theta)) and movers
    (own radial speed of random sign and size in ``mover_mps`` added), ranges at least
    ``min_sep_m`` apart, SNR per target (peak power over noise power per bin) uniform in
    ``snr_db``. ``truth`` is a dict of arrays beam, range_m, radial_mps, mover.
    """
    params = RadarParams()
    syn = Synthesizer(config, params)
    noise = noise_power_per_bin_w(config, params)
    az = 2.0 * np.pi * (np.arange(n_beams) + 0.5) / n_beams
    beams, ranges, radial, mover = [], [], [], []
    for b in range(n_beams):
        ns = rng.integers(n_static[0], n_static[1] + 1)
        nm = rng.integers(n_movers[0], n_movers[1] + 1)
        n = ns + nm
        while True:
            r = np.sort(rng.uniform(*range_m, n))
            if n < 2 or np.diff(r).min() >= min_sep_m:
                break
        v = np.full(n, -speed_mps * np.cos(az[b]))
        is_mover = np.zeros(n, bool)
        is_mover[rng.permutation(n)[:nm]] = True
        v[is_mover] += rng.choice([-1.0, 1.0], nm) * rng.uniform(*mover_mps, nm)
        beams += [b] * n
        ranges += list(r)
        radial += list(v)
        mover += list(is_mover)
    beam, ranges, radial = np.array(beams), np.array(ranges), np.array(radial)
    snr = rng.uniform(*snr_db, len(beam))
    power = noise * 10.0 ** (snr / 10.0)
    e = Echoes(beam, ranges, radial, power, rng.uniform(0, 2 * np.pi, len(beam)))
    up, down = syn.spectra(e, n_beams, rng)
    truth = {"beam": beam, "range_m": ranges, "radial_mps": radial, "mover": np.array(mover)}
    return up, down, az, truth


def score_pairs(beam, bin_up, bin_down, truth, tol_bins=1.0, config=IMPALA):
    """Per output pair: index of the true target whose up and down peaks it joins, else -1."""
    tu, td = beat_bins(truth["range_m"], truth["radial_mps"], config)
    same = truth["beam"][None, :] == np.asarray(beam)[:, None]
    ok = same & (np.abs(np.asarray(bin_up)[:, None] - tu) <= tol_bins) & (
        np.abs(np.asarray(bin_down)[:, None] - td) <= tol_bins)
    return np.where(ok.any(1), ok.argmax(1), -1)
