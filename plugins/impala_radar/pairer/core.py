"""Up/down peak pairing of a turn of triangular-FMCW spectra (seed 1 §2.4, eq. 3).

Pure functions; :mod:`impala_radar.pairer.component` wraps them in ``radar.FuzzyPairer``.

1. CFAR peaks of the up and down spectra with their features (:mod:`.peaks`).
2. Candidate pairs: every (up, down) peak of the same beam whose offset from the offset a
   static target would show, ``e(theta) = 2 f_d / bin_hz``, is within the gate of
   ``max_radial_speed_mps``.
3. Fuzzy score of each candidate (:mod:`.fuzzy`), then per beam the assignment maximising
   the total score, one peak used once (``scipy.optimize.linear_sum_assignment``), pairs
   below ``min_score`` dropped.
4. Range and radial speed of each pair by eq. (3).

The static offset ``e(theta)`` needs the ego speed: from a prior (odometer), or estimated
from the spectra themselves (:func:`xcorr_speed_prior`): static clutter makes the down
spectrum of every beam a copy of the up spectrum shifted by ``e(theta)``, so the speed
maximising the summed up/down cross-correlation at lags ``e(theta)`` over the turn is the
ego speed to a fraction of a bin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impala_msgs import SPEED_OF_LIGHT_MPS, RadarConfig

from ..peaks import Peaks, cfar_threshold, find_os_peaks, find_peaks, peak_features
from .fuzzy import pair_score

__all__ = [
    "Pairs", "detect_peaks", "range_from_beats_m", "radial_speed_from_beats_mps",
    "static_offset_bins", "candidate_pairs", "assign_pairs", "pair_turn", "xcorr_speed_prior",
    "nearest_peak_pairs",
]


def range_from_beats_m(f_up_hz, f_down_hz, config: RadarConfig):
    """Eq. (3): R = c / (8 dF Fm) (f_up + f_down)."""
    return SPEED_OF_LIGHT_MPS / (8.0 * config.bandwidth_hz * config.modulation_hz) * (
        np.asarray(f_up_hz) + np.asarray(f_down_hz))


def radial_speed_from_beats_mps(f_up_hz, f_down_hz, config: RadarConfig):
    """Eq. (3): V = c / (4 f0) (f_up - f_down), negative when the target approaches."""
    return SPEED_OF_LIGHT_MPS / (4.0 * config.f0_hz) * (np.asarray(f_up_hz) - np.asarray(f_down_hz))


def static_offset_bins(azimuth_rad, speed_mps: float, config: RadarConfig):
    """Up - down offset (bins) of a static target: 2 f_d / bin_hz, f_d = 2 V f0 / c (eq. 2),
    V = -speed cos(theta) (seed 1 eq. 7, theta from the heading)."""
    v = -speed_mps * np.cos(np.asarray(azimuth_rad, float))
    return 4.0 * config.f0_hz * v / (SPEED_OF_LIGHT_MPS * config.bin_hz)


def detect_peaks(power: np.ndarray, pfa: float, train: int, guard: int, method: str,
                 min_bin: int) -> Peaks:
    """CFAR peaks of a turn (beams, bins) with their features."""
    if method == "os":
        beam, bin_ = find_os_peaks(power, pfa, train, guard, min_bin)
    else:
        beam, bin_ = find_peaks(power, cfar_threshold(power, pfa, train, guard, method), min_bin)
    return peak_features(power, beam, bin_)


@dataclass
class Pairs:
    """Pairs of a turn: indices into the up and down peaks, their score and criteria."""

    up: Peaks
    down: Peaks
    iu: np.ndarray
    id: np.ndarray
    score: np.ndarray

    @property
    def beam(self) -> np.ndarray:
        return self.up.beam[self.iu]


def candidate_pairs(up: Peaks, down: Peaks, offset_bins: np.ndarray,
                    gate_bins: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(iu, id, position) of every same-beam pair within the gate; peaks sorted by beam.

    ``offset_bins`` is the static offset e per beam (indexed by beam number).
    """
    n_beams = int(max(up.beam.max(initial=-1), down.beam.max(initial=-1))) + 1
    cnt_d = np.bincount(down.beam, minlength=n_beams)
    start_d = np.concatenate([[0], np.cumsum(cnt_d)[:-1]])
    reps = cnt_d[up.beam]
    iu = np.repeat(np.arange(len(up)), reps)
    first = np.repeat(start_d[up.beam] - np.concatenate([[0], np.cumsum(reps)[:-1]]), reps)
    id_ = first + np.arange(len(iu))
    pos = np.abs(up.bin[iu] - down.bin[id_] - offset_bins[up.beam[iu]])
    keep = pos <= gate_bins
    return iu[keep], id_[keep], pos[keep]


def assign_pairs(beam: np.ndarray, iu: np.ndarray, id_: np.ndarray, score: np.ndarray,
                 tiebreak: np.ndarray, min_score: float) -> np.ndarray:
    """Indices of the chosen candidates: per beam the maximum-total-score assignment
    (one peak used once), then those scoring at least ``min_score``."""
    ok = score >= min_score
    beam, iu, id_, score, tiebreak = beam[ok], iu[ok], id_[ok], score[ok], tiebreak[ok]
    idx = np.nonzero(ok)[0]
    if len(idx) == 0:
        return idx
    # a beam whose candidates share no peak keeps them all; the others need an assignment
    shared = (np.bincount(iu)[iu] > 1) | (np.bincount(id_)[id_] > 1)
    conflict = np.bincount(beam, weights=shared, minlength=int(beam.max()) + 1) > 0
    chosen = [np.nonzero(~conflict[beam])[0]]
    cuts = np.nonzero(np.diff(beam))[0] + 1
    starts, ends = np.concatenate([[0], cuts]), np.concatenate([cuts, [len(beam)]])
    for s, e in zip(starts, ends, strict=True):
        if not conflict[beam[s]]:
            continue
        # peaks are sorted by beam: a beam's up (down) peaks are a contiguous index range
        u0, d0 = iu[s:e].min(), id_[s:e].min()
        ui, di = iu[s:e] - u0, id_[s:e] - d0
        cost = np.full((ui.max() + 1, di.max() + 1), 10.0)
        cost[ui, di] = -score[s:e] + 1e-3 * tiebreak[s:e]
        lut = np.full(cost.shape, -1)
        lut[ui, di] = np.arange(s, e)
        from scipy.optimize import linear_sum_assignment  # here, not at import: 0.3 s paid by every command

        r, c = linear_sum_assignment(cost)
        sel = lut[r, c]
        chosen.append(sel[sel >= 0])
    return idx[np.sort(np.concatenate(chosen))]


def pair_turn(up_power: np.ndarray, down_power: np.ndarray, azimuth_rad: np.ndarray,
              config: RadarConfig, speed_mps: float = 0.0, *, pfa: float = 1e-4,
              train: int = 12, guard: int = 4, cfar: str = "os", min_score: float = 0.45,
              max_radial_speed_mps: float = 30.0, min_range_m: float | None = None,
              membership: dict | None = None, rules: list | None = None) -> Pairs:
    """Detect, score and assign the up/down peak pairs of one turn (see module docstring)."""
    min_range = config.range_min_m if min_range_m is None else min_range_m
    min_bin = int(min_range / config.range_per_bin_m) - 2
    up = detect_peaks(up_power, pfa, train, guard, cfar, min_bin)
    down = detect_peaks(down_power, pfa, train, guard, cfar, min_bin)
    offset = static_offset_bins(azimuth_rad, speed_mps, config)
    gate = static_offset_bins(0.0, max_radial_speed_mps, config)
    iu, id_, pos = candidate_pairs(up, down, offset, abs(float(gate)))
    amp_db = np.abs(10.0 * np.log10(up.power[iu] / down.power[id_]))
    width = np.abs(np.log(up.width_bins[iu] / down.width_bins[id_]))
    sym = np.minimum(up.symmetry[iu], down.symmetry[id_])
    score = pair_score(pos, amp_db, width, sym, membership, rules)
    sel = assign_pairs(up.beam[iu], iu, id_, score, pos, min_score)
    iu, id_, score = iu[sel], id_[sel], score[sel]
    r = range_from_beats_m(up.bin[iu] * config.bin_hz, down.bin[id_] * config.bin_hz, config)
    keep = (r >= min_range) & (r <= config.range_max_m)
    return Pairs(up, down, iu[keep], id_[keep], score[keep])


def xcorr_speed_prior(up_power: np.ndarray, down_power: np.ndarray, azimuth_rad: np.ndarray,
                      config: RadarConfig, max_speed_mps: float = 20.0,
                      step_mps: float = 0.02) -> float:
    """Ego speed maximising sum_beams C_b(e_b(v)), C_b the up/down cross-correlation of
    whitened log spectra of beam b (FFT), e_b(v) the static offset (bins, linear interp.)."""
    def whiten(p: np.ndarray) -> np.ndarray:
        lp = np.log(np.maximum(p, 1e-30))
        if lp.dtype == np.float32 and lp.ndim == 2 and lp.shape[1]:
            from .._median_jit import medians  # here: numba is imported at the first turn, not with the plugin

            med = medians(p, lp)[:, None]  # np.median(lp)'s bits, in half its time
        else:
            med = np.median(lp, axis=1, keepdims=True)
        return np.maximum(lp - med - 1.0, 0.0)

    u, d = whiten(up_power), whiten(down_power)
    n = u.shape[1]
    import scipy.fft  # here, not at import: 0.2 s of every command's start-up (the component loads it in start())

    c = scipy.fft.irfft(scipy.fft.rfft(u, 2 * n, axis=1) * np.conj(scipy.fft.rfft(d, 2 * n, axis=1)),
                        2 * n, axis=1)  # c[b, lag mod 2n] = sum_k u[k + lag] d[k]
    flat = c.ravel()
    row_start = (np.arange(len(azimuth_rad)) * (2 * n))[None, :]
    from ._jit import lag_terms  # here: numba is imported at the first turn, not with the plugin

    cos_az = np.cos(np.asarray(azimuth_rad, float))
    scale, per = 4.0 * config.f0_hz, SPEED_OF_LIGHT_MPS * config.bin_hz

    def best(v: np.ndarray) -> float:
        if c.ndim == 2 and c.dtype in (np.float32, np.float64):
            terms = np.empty((len(v), len(azimuth_rad)))
            lag_terms(c, cos_az, np.ascontiguousarray(v, float), scale, per, terms)  # the formula below, fused
            return float(v[int(np.argmax(terms.sum(axis=1)))])
        lag = static_offset_bins(azimuth_rad[None, :], v[:, None], config)  # (V, B)
        lo = np.floor(lag)
        w = lag - lo
        i0 = lo.astype(np.int64)
        if i0.min() >= -2 * n and i0.max() < 2 * n:  # mod 2n without the division: a lag of less than 2n bins
            i0 += np.where(i0 < 0, 2 * n, 0)
        else:
            i0 %= 2 * n
        i1 = i0 + 1
        i1[i1 == 2 * n] = 0
        total = ((1 - w) * flat.take(row_start + i0) + w * flat.take(row_start + i1)).sum(axis=1)
        return float(v[int(np.argmax(total))])

    # coarse (a quarter of a bin of offset) then fine search
    coarse = best(np.arange(-max_speed_mps, max_speed_mps + 1e-9, 0.25))
    return best(coarse + np.arange(-0.3, 0.3 + 1e-9, step_mps))


def nearest_peak_pairs(up: Peaks, down: Peaks, max_offset_bins: float,
                       offset_bins: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Naive baseline: each up peak (in order) takes the nearest unused down peak of its beam
    (nearest to ``up - offset_bins[beam]`` when static offsets are given)."""
    ius, ids = [], []
    for b in np.unique(up.beam):
        us = np.nonzero(up.beam == b)[0]
        ds = list(np.nonzero(down.beam == b)[0])
        for i in us:
            if not ds:
                break
            e = 0.0 if offset_bins is None else offset_bins[b]
            dist = np.abs(down.bin[ds] - (up.bin[i] - e))
            k = int(np.argmin(dist))
            if dist[k] <= max_offset_bins:
                ius.append(i)
                ids.append(ds.pop(k))
    return np.array(ius, np.int64), np.array(ids, np.int64)
