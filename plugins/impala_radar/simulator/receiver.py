"""Receiver effects: transmitter leakage, phase-noise skirts, facade multipath ghosts.

**Transmitter leakage.** Part of the transmitted chirp couples into the receiver (antenna
mismatch, radome, circulator) with a delay of a few decimetres of path: every beam carries
an echo of power ``RadarParams.leakage_dbm`` at the slant range ``leakage_range_m`` with a
fixed phase (:func:`leakage_echoes`), whose window skirt covers the first range bins as in
real scans. The default, -100 dBm, is the level after the IF high-pass filter that real
FMCW receivers use to flatten the R^-4 law (about 30 dB above the IMPALA noise per bin).

**Phase noise.** The oscillator's single-sideband phase noise L(f) (dBc/Hz) falls at
20 dB/decade from ``phase_noise_dbc_hz`` at ``phase_noise_offset_hz``. The beat signal of an
echo of delay tau = 2 R / c keeps the residual phase noise of the difference
phi(t) - phi(t - tau) (range correlation, Budge & Burt 1993), so around an echo of power P
at beat frequency f_b each side carries the density::

    S(df) = P L(df) 4 sin^2(pi df tau)     (W/Hz, df the physical offset from f_b)

and one spectrum bin reads S ENBW / T (like thermal noise, T the ramp duration). The skirt
is noise-like: each bin gets S ENBW / T times an exponential variate
(:func:`phase_noise_skirts`). It is added for the echoes whose skirt can reach
``-10 dB`` of the thermal noise per bin, the main lobe (+-2 bins) excluded (the window's
own response dominates there).

**Multipath ghost (facade mirror).** A strong static scatterer seen via a facade twice
(radar -> facade -> target -> facade -> radar) appears at its mirror image across the facade
line, with the power of a target of RCS sigma Gamma^2 at the image's range (Gamma =
``multipath_reflection_db`` per bounce, power). :func:`mirror_images` returns the images of
the scatterers with RCS >= ``multipath_min_rcs_m2`` whose specular point lies on the
segment as seen from the turn's centre and that are on the radar's side of it; the images are
then simulated as static scatterers (not occlusion-tested: their ray crosses the facade by
construction).

**Output stage (Navtech).** A Navtech radar outputs 8-bit counts of 0.5 dB of power,
offset so that count 0 sits a little below the noise floor (the Oxford sample: 25 % of the
cells within 2-60 m are 0, the median far from the radar is 6 counts) and clipped at 255.
With ``RadarParams.adc_db_per_count`` set, :func:`adc_counts` maps each bin's power P to
``n = clip(round((10 log10(P / N) - adc_zero_db) / adc_db_per_count), 0, adc_max_count)``
(N the mean thermal noise per bin) and the beam carries ``10^(n adc_db_per_count / 10)``,
the same linear power an imported Navtech scan carries (``impala-flow import --db-per-count``).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["leakage_echoes", "phase_noise_skirts", "mirror_images", "adc_counts"]


def adc_counts(power_w: np.ndarray, noise_w: float, db_per_count: float, zero_db: float,
               max_count: int) -> np.ndarray:
    """Counts of a log-power output stage (module doc) as the linear power they stand for."""
    with np.errstate(divide="ignore"):  # a bin of zero power is count 0, not -inf
        db = 10.0 * np.log10(np.asarray(power_w, np.float64) / noise_w)
    n = np.clip(np.rint((db - zero_db) / db_per_count), 0, max_count)
    return (10.0 ** (n * (db_per_count / 10.0))).astype(np.float32)


def leakage_echoes(n_beams: int, power_w: float, range_m: float):
    """(beam, range_m, radial_mps, power_w, phase_rad) of one leakage echo per beam."""
    beam = np.arange(n_beams)
    return (beam, np.full(n_beams, range_m), np.zeros(n_beams), np.full(n_beams, power_w),
            np.zeros(n_beams))


def skirt_density(df_hz, power_w, range_m, l_ref_dbc_hz: float, f_ref_hz: float):
    """S(df) = P L(df) 4 sin^2(pi df tau), L(df) = L_ref (f_ref / df)^2 (W/Hz per side)."""
    tau_s = 2.0 * range_m / 299_792_458.0
    df = np.maximum(np.abs(df_hz), 1e-9)
    ell = 10.0 ** (l_ref_dbc_hz / 10.0) * (f_ref_hz / df) ** 2
    return power_w * ell * 4.0 * np.sin(math.pi * df * tau_s) ** 2


def skirt_echoes(power_w, range_m, ramp_s: float, enbw: float, noise_per_bin_w: float, l_ref_dbc_hz: float,
                 f_ref_hz: float) -> np.ndarray:
    """Indices of the echoes whose skirts :func:`phase_noise_skirts` draws: those whose flat skirt
    level reaches a tenth of the noise per bin (a subset of the echoes in the same order has the
    same skirts and draws)."""
    # the flat part of S (df >> 1/tau is never reached here): 4 pi^2 L_ref f_ref^2 tau^2 P, in one
    # compiled pass with the arithmetic of the numpy expression (tests/radar/test_sim_turn_kernels.py)
    from . import synth_kernels  # numba: compiled (cached) at the first call, not at import

    return synth_kernels.skirt_select(np.ascontiguousarray(power_w, float), np.ascontiguousarray(range_m, float),
                                      10.0 ** (l_ref_dbc_hz / 10.0), 2.0 * math.pi * f_ref_hz, enbw, ramp_s,
                                      0.1 * noise_per_bin_w)


def phase_noise_skirts(beam, f_hz, power_w, range_m, n_beams: int, bin_hz: float, n_bins: int,
                       hz_per_bin_phys: float, ramp_s: float, enbw: float, noise_per_bin_w: float,
                       l_ref_dbc_hz: float, f_ref_hz: float, rng: np.random.Generator):
    """(n_beams, n_bins) skirt powers to add to the spectra (module doc)."""
    out = np.zeros((n_beams, n_bins))
    if len(power_w) == 0:
        return out
    sel = skirt_echoes(power_w, range_m, ramp_s, enbw, noise_per_bin_w, l_ref_dbc_hz, f_ref_hz)
    if sel.size == 0:
        return out
    k = np.arange(n_bins)
    df_bins = k[None, :] - (f_hz[sel] / bin_hz)[:, None]  # offset in bins
    dens = skirt_density(df_bins * hz_per_bin_phys, power_w[sel, None], range_m[sel, None],
                         l_ref_dbc_hz, f_ref_hz)
    dens[np.abs(df_bins) < 2.0] = 0.0
    per_bin = dens * enbw / ramp_s * rng.exponential(1.0, dens.shape)
    flat = (beam[sel].astype(np.intp)[:, None] * n_bins + k[None, :]).ravel()
    return np.bincount(flat, per_bin.ravel(), n_beams * n_bins).reshape(n_beams, n_bins)


def mirror_images(x_m, y_m, rcs_m2, center_xy_m, segments: np.ndarray, min_rcs_m2: float):
    """Mirror images (parent index, x, y) of strong scatterers across facade segments."""
    strong = np.nonzero(rcs_m2 >= min_rcs_m2)[0]
    if strong.size == 0 or len(segments) == 0:
        return np.zeros(0, np.intp), np.zeros(0), np.zeros(0)
    a, b = segments[:, :2], segments[:, 2:]
    d = b - a
    length = np.hypot(d[:, 0], d[:, 1])
    ok_seg = length > 1e-6
    a, d, length = a[ok_seg], d[ok_seg], length[ok_seg]
    t_hat = d / length[:, None]
    n_hat = np.column_stack([-t_hat[:, 1], t_hat[:, 0]])
    c = np.asarray(center_xy_m, float)
    side_radar = np.einsum("ij,ij->i", c[None, :] - a, n_hat)  # (G,) signed distance of the radar
    px, py = x_m[strong][:, None], y_m[strong][:, None]  # (S, 1)
    side_p = (px - a[:, 0]) * n_hat[:, 0] + (py - a[:, 1]) * n_hat[:, 1]  # (S, G)
    ix, iy = px - 2.0 * side_p * n_hat[:, 0], py - 2.0 * side_p * n_hat[:, 1]
    # the ray centre -> image crosses the facade line at parameter s = side_r / (side_r - side_i)
    side_i = -side_p
    same_side = (side_p * side_radar > 0.0) & (np.abs(side_p) > 0.05)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = side_radar / (side_radar - side_i)
        hx, hy = c[0] + s * (ix - c[0]), c[1] + s * (iy - c[1])
        along = (hx - a[:, 0]) * t_hat[:, 0] + (hy - a[:, 1]) * t_hat[:, 1]
    valid = same_side & (along >= 0.0) & (along <= length)
    si, gi = np.nonzero(valid)
    return strong[si], ix[si, gi], iy[si, gi]
