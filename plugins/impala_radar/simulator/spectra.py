"""Per-beam synthesis of the up- and down-ramp power spectra of a rotating FMCW radar.

Signal model (seed 1 eq. 1). In one beam each ramp's beat signal is the coherent sum::

    s(t) = sum_i a_i cos(2 pi f_i t + phi_i),   t in [-T/2, T/2),  T = 1 / (2 Fm)
    f_i  = f_r + f_d (up ramp),  f_r - f_d (down ramp)                         (eq. 2)
    f_r  = 4 dF Fm R_i / c,      f_d = 2 V_i f0 / c     (V_i < 0 approaching)
    a_i  = sqrt(2 P_i),  P_i = EIRP G lambda^2 sigma_i g2_i / ((4 pi)^3 R_i^4)  (radar eq.)
    phi_i = psi_i + 4 pi (R_i -+ V_i T / 2) / lambda

``psi_i`` is a random phase fixed per scatterer; with the range phase 4 pi R / lambda it
makes the coherent sum speckle (seed 1 §2.3). The up ramp is centred T/2 before the beam
time, the down ramp T/2 after it. ``R_i`` is the slant range (radar ``height_m`` above the
ground), ``V_i = dR_i/dt`` from the vehicle's and the scatterer's velocities. ``g2`` is the
two-way normalised antenna power pattern: in azimuth the Hann-on-pedestal aperture of
:mod:`impala_radar.simulator.antenna` with its sidelobes (``sidelobe_db``, default -25 dB one way),
or the Gaussian exp(-8 ln2 (d_az / theta_3)^2) with ``sidelobe_db = None``; in elevation
exp(-8 ln2 (el / theta_e)^2). Each scatterer is evaluated within the azimuth window where
its echo can exceed the culling level, at most ``pattern_cut_db`` (60 dB) down.

Power budget: P_t G^2 = ``RadarParams.pt_g2_w``: P_t = ``tx_power_dbm`` and G =
``antenna_gain_db`` when given (K2Pi, seed 2 Table I: 20 dBm, 20 dB), otherwise
G = 26 000 / (theta_3 theta_e in degrees) and P_t = EIRP / G (IMPALA: EIRP 18 dBm, seed 1
Fig. 2). Distributed clutter follows the constant-gamma grazing law, and vegetation
moves between turns (:mod:`impala_radar.simulator.clutter`); transmitter leakage, phase-noise
skirts and facade ghosts are in :mod:`impala_radar.simulator.receiver`.

Single-ramp (sawtooth) radars (``RadarConfig.doppler = False``, the Navtech): one ramp
of duration 1/Fm per beam sweeping dF, slope S = dF Fm, centred on the beam time; beat
f = 2 S R / c + f_d. The spectrum is indexed on RadarConfig's nominal axis (bin_hz, on
which f_r = 4 dF Fm R / c), i.e. nominal = 2 x physical Hz, so ``range_of_bin_m`` and
dR = c / (2 dF) hold, and the Doppler moves the apparent range by dR = c f_d / (2 S) =
V f0 / (dF Fm) (Navtech: 0.0478 s x V, 4.8 cm per m/s). The noise is k T0 F per physical
hertz, so the noise per bin, k T0 F ENBW / T, is 3 dB lower than a roof ramp's (T = 1/Fm).

Fastest exact formulation. Each ramp is sampled at fs = 2 n_bins bin_hz (N = fs T samples,
288 for IMPALA), weighted by the window w (Hann by default, ``rect`` for the unweighted
Rayleigh resolution of eq. 4), zero-padded to L = fs / bin_hz and Fourier transformed,
as the radar's processor does. The time signal z[n] = sum_i c_i exp(j x_i n),
c_i = a_i exp(j phi_i), x_i = 2 pi f_i / fs, s = Re z, is a type-1 non-uniform FFT, computed
by gridding (Dutt-Rokhlin, Greengard-Lee; FINUFFT's "exponential of semicircle" kernel)::

    b[m] = sum_i c_i phi(m h - x_i),       h = 2 pi / M,  M = 2 N       (spread, 6 points)
    phi(x) = exp(beta (sqrt(1 - (x / alpha)^2) - 1)),  alpha = 3 h,  beta = 2.3 * 6
    z[n] = 2 pi IFFT_M(b)[n] / phi^(n),    phi^(k) = integral phi(x) cos(k x) dx

Kernel and phasors are evaluated in float32 (SIMD; relative error 1e-7). The error of the
resulting power spectrum is below -100 dB relative to the strongest echo (checked against
direct summation in tests/radar/test_sim_spectra.py), far under the Hann sidelobes and the
thermal noise. Cost per ramp: 6 kernel values per echo (one compiled spreading loop over a
whole turn, :mod:`.synth_kernels`, the exponential being numpy's) plus two FFTs per beam, versus
29 bins per echo for a Hann DTFT summed directly in the frequency domain and truncated at
-60 dB, and N exponentials per echo for time-domain synthesis. The window is applied in the
time domain, so any window and the exact fold of negative beat frequencies (near, fast
targets) of the real mixer output come for free; echoes with |f| >= fs/2 are removed (ideal anti-aliasing filter).

Echoes weaker than the noise per bin by ``cull_below_noise_db`` (30 dB) are dropped when
thermal noise is on: the window spreads each over ~4 bins and a beam holds far fewer of
them than bins, so they change the noise floor by < 0.1 % (pattern tails of far clutter).

Thermal noise: white, k T0 F per hertz over the real signal's band fs/2, i.e. per-sample
variance k T0 F fs / 2, with noise figure F = 10 dB (a 24 GHz MMIC receiver with its mixer
and IF amplifier). Scaling: X = (2 / sum w) FFT(w s) and power = |X|^2 / 2, so a tone of
received power P centred on a bin reads P watts; the noise floor per bin is
k T0 F ENBW / T (ENBW = 1.5 for Hann): ``noise_power_per_bin_w``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.fft

from impala_msgs import SPEED_OF_LIGHT_MPS, RadarConfig

from .antenna import AzimuthPattern
from .clutter import grazing_factor
from .receiver import phase_noise_skirts, skirt_echoes

__all__ = [
    "RadarParams", "Echoes", "Synthesizer", "beat_frequencies_hz", "received_power_w",
    "two_way_gain", "echoes", "noise_power_per_bin_w", "BOLTZMANN_JPK", "azimuth_pattern",
    "apparent_range_shift_m", "pair_echoes", "select_pairs",
]

BOLTZMANN_JPK = 1.380649e-23
_KERNEL_WIDTH = 6  # grid points per echo (even); beta = 2.3 w for oversampling 2 (FINUFFT)
_KERNEL_BETA = 2.3 * _KERNEL_WIDTH


def _kernel(u):
    """ES kernel phi(u) = exp(beta (sqrt(1 - u^2) - 1)), u in units of its half-width."""
    one = u.dtype.type(1.0)
    return np.exp(u.dtype.type(_KERNEL_BETA) * (np.sqrt(np.maximum(one - u * u, 0)) - one))


@dataclass(frozen=True)
class RadarParams:
    """Radar properties the message contract does not carry (documented assumptions)."""

    eirp_dbm: float = 18.0  # seed 1 Fig. 2; used when tx_power_dbm is None (P_t = EIRP / G)
    tx_power_dbm: float | None = None  # P_t (K2Pi, seed 2 Table I: 20 dBm); None: EIRP / G
    antenna_gain_db: float | None = None  # G (K2Pi: 20 dB); None: 26 000 / (theta_az theta_el)
    noise_figure_db: float = 10.0
    temperature_k: float = 290.0
    elevation_beam_width_rad: float = math.radians(20.0)  # fan beam (assumed)
    pattern_cut_db: float = 60.0  # deepest two-way pattern level simulated (sidelobes)
    sidelobe_db: float | None = -25.0  # one-way highest azimuth sidelobe; None: Gaussian beam
    clutter_cut_db: float = 15.0  # two-way pattern depth for distributed clutter (0.7 % of power left out)
    window_below_noise_db: float = 10.0  # a scatterer's azimuth window ends this far below noise
    window: str = "hann"  # "hann" or "rect"
    thermal_noise: bool = True
    cull_below_noise_db: float = 30.0  # drop echoes this far below the noise per bin
    clockwise: bool = False  # sense of the antenna's rotation seen from above (Navtech: clockwise)
    start_azimuth_rad: float = 0.0  # azimuth where each turn starts (vehicle frame, CCW from the heading)
    grazing_ref_deg: float | None = 5.0  # clutter sigma0 given at this grazing angle (constant gamma)
    speckle_range_m: float = 20.0  # clutter tiles split for developed speckle within this range
    speckle_max_split: int = 8  # at most q x q sub-points per tile
    vegetation_motion_m: float = 1.0e-3  # rms leaf displacement between turns (phase jitter)
    vegetation_rcs_jitter_db: float = 1.5  # per-turn log-normal RCS jitter of leaves (dB std)
    shadows: bool = True  # trunks, tree crowns, parked and moving cars shadow what is behind
    leakage_dbm: float | None = -100.0  # transmitter leakage after the IF high-pass; None: off
    leakage_range_m: float = 0.3
    phase_noise_dbc_hz: float | None = -95.0  # SSB phase noise at phase_noise_offset_hz; None: off
    phase_noise_offset_hz: float = 100.0e3
    multipath_reflection_db: float | None = -6.0  # facade power reflection per bounce; None: off
    multipath_min_rcs_m2: float = 1.0  # scatterers mirrored by facades (ghosts)
    adc_db_per_count: float | None = None  # log-power output stage (Navtech: 0.5 dB); None: raw power
    adc_zero_db: float = -4.6  # level of count 0 re the mean thermal noise per bin (dB)
    adc_max_count: int = 255  # the largest count (8 bits)

    def __post_init__(self) -> None:
        checks = [
            ("sidelobe_db", self.sidelobe_db is None or -42.7 <= self.sidelobe_db <= -13.26,
             "in [-42.7, -13.26] dB (Hamming .. uniform aperture) or null"),
            ("grazing_ref_deg", self.grazing_ref_deg is None or 0.0 < self.grazing_ref_deg <= 90.0,
             "in (0, 90] or null"),
            ("pattern_cut_db", self.pattern_cut_db > 0.0, "> 0"),
            ("clutter_cut_db", self.clutter_cut_db > 0.0, "> 0"),
            ("speckle_range_m", self.speckle_range_m >= 0.0, ">= 0"),
            ("speckle_max_split", self.speckle_max_split >= 1, ">= 1"),
            ("vegetation_motion_m", self.vegetation_motion_m >= 0.0, ">= 0"),
            ("vegetation_rcs_jitter_db", self.vegetation_rcs_jitter_db >= 0.0, ">= 0"),
            ("leakage_range_m", self.leakage_range_m > 0.0, "> 0"),
            ("phase_noise_offset_hz", self.phase_noise_offset_hz > 0.0, "> 0"),
            ("multipath_reflection_db", self.multipath_reflection_db is None or self.multipath_reflection_db <= 0.0,
             "<= 0 dB or null"),
            ("multipath_min_rcs_m2", self.multipath_min_rcs_m2 >= 0.0, ">= 0"),
            ("temperature_k", self.temperature_k > 0.0, "> 0"),
            ("adc_db_per_count", self.adc_db_per_count is None or self.adc_db_per_count > 0.0, "> 0 or null"),
            ("adc_max_count", self.adc_max_count >= 1, ">= 1"),
        ]
        for name, ok, what in checks:
            if not ok:
                raise ValueError(f"radar.{name} = {getattr(self, name)!r} must be {what}")

    def antenna_gain(self, config: RadarConfig) -> float:
        """Antenna gain G ~ 26 000 / (theta_az theta_el in degrees) (65 % efficiency)."""
        return 26000.0 / (math.degrees(config.beam_width_rad)
                          * math.degrees(self.elevation_beam_width_rad))

    def pt_g2_w(self, config: RadarConfig) -> float:
        """P_t G^2 (W) of the radar equation from tx_power_dbm / antenna_gain_db / eirp_dbm."""
        gain = (10.0 ** (self.antenna_gain_db / 10.0) if self.antenna_gain_db is not None
                else self.antenna_gain(config))
        pt_w = (10.0 ** (self.tx_power_dbm / 10.0) * 1e-3 if self.tx_power_dbm is not None
                else 10.0 ** (self.eirp_dbm / 10.0) * 1e-3 / gain)
        return pt_w * gain * gain

    def cut_azimuth_rad(self, config: RadarConfig) -> float:
        """Half-width in azimuth beyond which the two-way pattern stays ``pattern_cut_db`` down."""
        pattern = azimuth_pattern(config.beam_width_rad, self.sidelobe_db)
        return float(pattern.window_rad(10.0 ** (-self.pattern_cut_db / 10.0)))


@lru_cache(maxsize=32)
def azimuth_pattern(beam_width_rad: float, sidelobe_db: float | None) -> AzimuthPattern:
    """The (cached) azimuth pattern of a beam width and sidelobe level."""
    return AzimuthPattern(beam_width_rad, sidelobe_db)


def apparent_range_shift_m(radial_mps, config: RadarConfig):
    """Single-ramp range-Doppler coupling: dR = c f_d / (2 S) = V f0 / (dF Fm), S = dF Fm."""
    return np.asarray(radial_mps) * config.f0_hz / (config.bandwidth_hz * config.modulation_hz)


def beat_frequencies_hz(range_m, radial_mps, config: RadarConfig):
    """Seed 1 eq. (2): (f_r, f_d) = (4 dF Fm R / c, 2 V f0 / c)."""
    f_r = 4.0 * config.bandwidth_hz * config.modulation_hz / SPEED_OF_LIGHT_MPS * range_m
    f_d = 2.0 * config.f0_hz / SPEED_OF_LIGHT_MPS * radial_mps
    return f_r, f_d


def two_way_gain(d_azimuth_rad, elevation_rad, config: RadarConfig, params: RadarParams):
    """Two-way normalised pattern: azimuth (:mod:`.antenna`) x exp(-8 ln2 (el / theta_e)^2)."""
    g_az = azimuth_pattern(config.beam_width_rad, params.sidelobe_db).gain2(d_azimuth_rad)
    return g_az * np.exp(-8.0 * math.log(2.0) * (elevation_rad / params.elevation_beam_width_rad) ** 2)


def received_power_w(range_m, rcs_m2, gain2, config: RadarConfig, params: RadarParams):
    """Radar equation P_r = P_t G^2 lambda^2 sigma g2 / ((4 pi)^3 R^4) (``RadarParams.pt_g2_w``)."""
    lam = SPEED_OF_LIGHT_MPS / config.f0_hz
    k = params.pt_g2_w(config) * lam**2 / (4.0 * math.pi) ** 3
    return k * rcs_m2 * gain2 / range_m**4


def noise_power_per_bin_w(config: RadarConfig, params: RadarParams) -> float:
    """Expected thermal noise power per spectrum bin, k T0 F ENBW / T."""
    return Synthesizer(config, params).noise_per_bin_w


@dataclass
class Echoes:
    """Scatterer-beam pairs seen by a turn: beam index, slant range, radial speed, power, phase."""

    beam: np.ndarray
    range_m: np.ndarray
    radial_mps: np.ndarray
    power_w: np.ndarray
    phase_rad: np.ndarray

    @classmethod
    def concat(cls, parts: list[Echoes]) -> Echoes:
        if not parts:
            e = np.zeros(0)
            return cls(np.zeros(0, np.int64), e, e, e, e)
        if len(parts) == 1:  # the part itself (its arrays are not copied)
            return parts[0]
        return cls(*(np.concatenate([getattr(p, f) for p in parts])
                     for f in ("beam", "range_m", "radial_mps", "power_w", "phase_rad")))


def echoes(beam_index, radar_xy_m, radar_vxy_mps, beam_dir_rad, sc_xy_m, sc_z_m, sc_vxy_mps,
           rcs_m2, phase_rad, config: RadarConfig, params: RadarParams,
           visible=None, range_limit_m: float = np.inf, cut_rad=None, area_m2=None) -> Echoes:
    """Echoes of scatterers inside the beam pattern, dense over (beams x scatterers).

    Beam-side arrays have a leading axis B (``radar_xy_m`` (B, 2), ``beam_dir_rad`` (B,) the
    world direction of the antenna); scatterer-side arrays are (S, ...) or (B, S, ...) for
    scatterers moving during the turn; ``sc_vxy_mps`` may be None (static); ``visible`` is
    None or a bool or float (two-way transmission, 0 = shadowed) array broadcastable to
    (B, S); ``cut_rad`` the azimuth half-window per scatterer (default: ``pattern_cut_db``);
    ``area_m2`` > 0 marks distributed clutter (grazing law, :mod:`.clutter`).
    """
    tan_cut = np.tan(params.cut_azimuth_rad(config) if cut_rad is None else np.minimum(cut_rad, 1.5))
    bi, si, dx, dy, along, across, r2 = select_pairs(radar_xy_m, beam_dir_rad, sc_xy_m, tan_cut,
                                               range_limit_m**2, visible)
    shape = (len(beam_dir_rad), sc_xy_m.shape[-2])

    def at(a):  # gather a scatterer-side (S,) or (B, S) array at the selected pairs
        a = np.asarray(a)
        return a[si] if a.ndim == 1 and a.shape[0] == shape[1] else np.broadcast_to(a, shape)[bi, si]

    return pair_echoes(np.asarray(beam_index)[bi], radar_vxy_mps[bi], dx, dy, along, across, r2, at(sc_z_m),
                       None if sc_vxy_mps is None else np.column_stack([at(sc_vxy_mps[..., 0]),
                                                                        at(sc_vxy_mps[..., 1])]),
                       at(rcs_m2), at(phase_rad), None if area_m2 is None else at(area_m2),
                       at(visible) if visible is not None and np.asarray(visible).dtype != bool else None,
                       config, params)


def pair_echoes(beam, radar_vxy_mps, dx, dy, along, across, r2, sc_z_m, sc_vxy_mps, rcs_m2, phase_rad,
                area_m2, transmission, config: RadarConfig, params: RadarParams) -> Echoes:
    """Echoes of (beam, scatterer) pairs (:func:`echoes` once the pairs are selected): one
    value per pair in every array, ``dx, dy`` the scatterer's offset from the radar,
    ``along, across`` along and across the antenna axis, ``r2`` = dx^2 + dy^2;
    ``sc_vxy_mps`` (n, 2) or None (static), ``area_m2`` None or > 0 for clutter,
    ``transmission`` None or the two-way transmission of the shadowing discs."""
    r_h = np.sqrt(r2)
    dz = sc_z_m - config.height_m
    range_m = np.sqrt(r_h * r_h + dz * dz)
    gain2 = two_way_gain(np.arctan2(across, along), np.arctan2(dz, r_h), config, params)
    v_rel_x, v_rel_y = -radar_vxy_mps[:, 0], -radar_vxy_mps[:, 1]
    if sc_vxy_mps is not None:
        v_rel_x = v_rel_x + sc_vxy_mps[:, 0]
        v_rel_y = v_rel_y + sc_vxy_mps[:, 1]
    radial = (dx * v_rel_x + dy * v_rel_y) / range_m  # V = dR/dt, eq. (2) sign convention
    rcs = rcs_m2
    if area_m2 is not None:
        rcs = rcs * grazing_factor(range_m, dz, area_m2, params.grazing_ref_deg)
    if transmission is not None:
        rcs = rcs * transmission
    power = received_power_w(range_m, rcs, gain2, config, params)
    keep = gain2 >= 10.0 ** (-params.pattern_cut_db / 10.0)
    return Echoes(beam[keep], range_m[keep], radial[keep], power[keep], phase_rad[keep])


def select_pairs(radar_xy_m, beam_dir_rad, sc_xy_m, tan_cut, r2_max: float, visible):
    """(beam, scatterer) pairs in front of the antenna within ``tan_cut`` (np.nonzero order),
    with dx, dy, along, across, r2; static scatterers by a compiled loop (:mod:`.kernels`),
    moving ones ((B, S, 2) positions) dense in numpy, with the same arithmetic."""
    c, s = np.cos(beam_dir_rad), np.sin(beam_dir_rad)
    vis = None if visible is None else np.asarray(visible) > 0
    if sc_xy_m.ndim == 2 and (vis is None or vis.shape == (len(sc_xy_m),)):
        from . import kernels  # numba: compiled (cached) at the first call, not at import

        vis = np.ones(len(sc_xy_m), bool) if vis is None else vis
        bi, si, d = kernels.static_pairs(radar_xy_m[:, 0].copy(), radar_xy_m[:, 1].copy(), c, s,
                                         sc_xy_m[:, 0].copy(), sc_xy_m[:, 1].copy(),
                                         np.broadcast_to(tan_cut, vis.shape).astype(float), float(r2_max), vis)
        return bi, si, *d
    dx, dy = sc_xy_m[..., 0] - radar_xy_m[:, 0, None], sc_xy_m[..., 1] - radar_xy_m[:, 1, None]
    c, s = c[:, None], s[:, None]
    along, across = dx * c + dy * s, dy * c - dx * s
    r2 = dx * dx + dy * dy
    mask = (along > 0.0) & (np.abs(across) <= tan_cut * along)
    mask &= r2 <= r2_max
    if vis is not None:
        mask &= vis
    bi, si = np.nonzero(mask)
    return bi, si, dx[bi, si], dy[bi, si], along[bi, si], across[bi, si], r2[bi, si]


class Synthesizer:
    """Up/down power spectra of many beams from their echoes (NUFFT formulation above)."""

    def __init__(self, config: RadarConfig, params: RadarParams = RadarParams(), pool=None):
        self.config, self.params = config, params
        self.pool = pool  # an Executor: the down ramp's NUFFT beside the up ramp's (same bits)
        self.fs_hz = 2.0 * config.n_bins * config.bin_hz
        # roof: two ramps of 1/(2 Fm); single ramp: one of 1/Fm, labelled on the nominal axis
        self.single_ramp = not config.doppler
        self.hz_per_nominal_hz = 0.5 if self.single_ramp else 1.0  # physical / nominal beat Hz
        self.doppler_factor = 2.0 if self.single_ramp else 1.0  # nominal Hz per Hz of f_d
        self.ramp_s = (1.0 if self.single_ramp else 0.5) / config.modulation_hz
        self.n_samples = int(round(self.fs_hz * 0.5 / config.modulation_hz))
        self.n_fft = int(round(self.fs_hz / config.bin_hz))
        if self.n_samples > self.n_fft:
            raise ValueError(f"{config.name}: bin_hz {config.bin_hz} is wider than 1/T")
        n = np.arange(self.n_samples) - self.n_samples // 2
        self.n_grid = 2 * self.n_samples
        self._time_index = n % self.n_grid
        h = 2.0 * math.pi / self.n_grid
        alpha = _KERNEL_WIDTH * h / 2.0
        xq, wq = np.polynomial.legendre.leggauss(200)
        phihat = alpha * (np.cos(np.outer(n, alpha * xq)) @ (wq * _kernel(xq)))
        self._deapodize = 2.0 * math.pi / phihat
        self._offsets = (np.arange(_KERNEL_WIDTH) - (_KERNEL_WIDTH // 2 - 1)).astype(np.float32)
        self._u_scale = np.float32(2.0 / _KERNEL_WIDTH)
        if params.window == "hann":
            self.window = 0.5 + 0.5 * np.cos(2.0 * math.pi * n / self.n_samples)
        elif params.window == "rect":
            self.window = np.ones(self.n_samples)
        else:
            raise ValueError(f"unknown window {params.window!r}; valid: hann, rect")
        self._scale = 2.0 / self.window.sum()
        f_noise = 10.0 ** (params.noise_figure_db / 10.0)
        self.noise_sigma = math.sqrt(BOLTZMANN_JPK * params.temperature_k * f_noise
                                     * self.fs_hz * self.hz_per_nominal_hz / 2.0)
        self.lambda_m = SPEED_OF_LIGHT_MPS / config.f0_hz
        w = self.window
        self.noise_per_bin_w = float(self.noise_sigma**2 * 2.0 * np.sum(w**2) / w.sum() ** 2)
        self.enbw_bins = float(len(w) * np.sum(w**2) / w.sum() ** 2)  # in 1/T units (1.5 Hann)
        self._cull_w = self.noise_per_bin_w * 10.0 ** (-params.cull_below_noise_db / 10.0)

    def signal(self, beam, f_hz, amplitude, phase_rad, n_beams: int) -> np.ndarray:
        """Complex time samples z (n_beams, N) of sum_i a_i exp(j(2 pi f_i t + phi_i))."""
        # Hand-written type-1 NUFFT (finufft does this; not a dependency, and batching all
        # beams of a turn into one spreading pass is what makes it fast here).
        ok = np.abs(f_hz) < 0.5 * self.fs_hz
        if not ok.all():
            f_hz, amplitude, phase_rad, beam = f_hz[ok], amplitude[ok], phase_rad[ok], beam[ok]
        from . import synth_kernels  # numba: compiled (cached) at the first call, not at import

        m_grid, width = self.n_grid, _KERNEL_WIDTH
        x = synth_kernels.grid_positions(np.asarray(f_hz, float), m_grid / self.fs_hz, float(m_grid))  # [0, M)
        row = m_grid + width - 1  # one padded row per beam; wrapped columns folded in _grid
        # phi(m h - x_i) at the 6 grid points around x_i, in float32 (error 1e-7 << 1e-5)
        arg, base = synth_kernels.kernel_arguments(x, np.asarray(beam), row, self._offsets, self._u_scale,
                                              np.float32(_KERNEL_BETA))
        phase32 = synth_kernels.wrap_phase32(np.asarray(phase_rad, float))
        z = self._grid(arg, base, phase32, amplitude.astype(np.float32), n_beams)
        return z[:, self._time_index] * self._deapodize

    def _grid(self, arg, base, phase32, amp32, n_beams: int) -> np.ndarray:
        """The IFFT (n_beams, M) of the spread grid from the kernel's exponents ``arg`` at the grid
        points from ``base`` on, the phases and amplitudes (float32) of the echoes in the band."""
        from . import synth_kernels  # numba: compiled (cached) at the first call, not at import

        ker = np.exp(arg, out=arg)  # numpy's exp: the bits of _kernel
        b = synth_kernels.spread_fold(base, ker, amp32, np.cos(phase32), np.sin(phase32), n_beams, self.n_grid,
                                _KERNEL_WIDTH // 2 - 1)
        return scipy.fft.ifft(b, axis=1)

    def power_spectrum(self, beat_signal: np.ndarray) -> np.ndarray:
        """Windowed, zero-padded power spectrum (n_beams, n_bins) float32 of real samples."""
        x = scipy.fft.rfft(beat_signal * self.window, n=self.n_fft, axis=1)
        x = x[:, : self.config.n_bins] * self._scale
        return (0.5 * (x.real**2 + x.imag**2)).astype(np.float32)

    def _draws(self, beam, f_hz, power_w, n_beams: int, rng, range_m):
        """The random parts of a ramp, in this order: thermal noise samples and phase-noise skirts
        (None when off, or when no echo has any: adding zeros to powers >= 0 changes no bit)."""
        noise = skirts = None
        if self.params.thermal_noise:
            noise = rng.standard_normal((n_beams, self.n_samples))
            noise *= self.noise_sigma
        p = self.params
        if p.phase_noise_dbc_hz is not None and range_m is not None and len(power_w):
            skirts = phase_noise_skirts(
                beam, f_hz, power_w, range_m, n_beams, self.config.bin_hz, self.config.n_bins,
                self.config.bin_hz * self.hz_per_nominal_hz, self.ramp_s, self.enbw_bins,
                self.noise_per_bin_w, p.phase_noise_dbc_hz, p.phase_noise_offset_hz, rng).astype(np.float32)
        return noise, skirts

    def spectra(self, e: Echoes, n_beams: int, rng) -> tuple[np.ndarray, np.ndarray]:
        """(up, down) power spectra; ``down`` is (n_beams, 0) for a radar without Doppler.

        Roof (``config.doppler``): up ramp centred T/2 before the beam time, down ramp T/2
        after it, f = f_r +- f_d. Single ramp (sawtooth, ``doppler = False``): one ramp of
        1/Fm centred on the beam time sweeping dF, slope S = dF Fm, physical beat
        f = 2 S R / c + f_d; the spectrum axis is RadarConfig's nominal one (bin_hz per bin,
        f_nominal = 2 f = f_r + 2 f_d of eq. 2), so ``range_of_bin_m`` holds and a radial
        speed V moves the apparent range by V f0 / (dF Fm) (:func:`apparent_range_shift_m`).
        """
        return self.synthesize(*self.draw(e, n_beams, rng), n_beams, self.pool)

    def draw(self, e: Echoes | list[Echoes], n_beams: int, rng) -> tuple[list[Echoes], list]:
        """The echoes kept (weak ones culled) and the random draws of :meth:`spectra`, in its
        order: per ramp (up then down) the thermal noise and the phase-noise skirts. The rest
        (:meth:`synthesize`) draws nothing, so it may run on another thread, later. ``e`` may be
        the parts of a turn's echoes (their concatenation, left to :meth:`synthesize`); both steps are
        element-wise, so part by part is the same as on the whole."""
        parts = [e] if isinstance(e, Echoes) else list(e)
        if self.params.thermal_noise:
            for i, q in enumerate(parts):
                strong = q.power_w >= self._cull_w
                if not strong.all():
                    parts[i] = Echoes(q.beam[strong], q.range_m[strong], q.radial_mps[strong],
                                      q.power_w[strong], q.phase_rad[strong])
        # the skirts only need the echoes strong enough to have some (the same skirts and draws):
        # found once for both ramps, and their beat frequencies only
        p = self.params
        if p.phase_noise_dbc_hz is not None:
            sel = []
            for q in parts:
                k = skirt_echoes(q.power_w, q.range_m, self.ramp_s, self.enbw_bins, self.noise_per_bin_w,
                                 p.phase_noise_dbc_hz, p.phase_noise_offset_hz)
                sel.append(Echoes(q.beam[k], q.range_m[k], q.radial_mps[k], q.power_w[k], q.phase_rad[k]))
            s = Echoes.concat(sel)
        else:
            s = Echoes.concat(parts)
        return parts, [self._draws(s.beam, self._beat_hz(s, mode), s.power_w, n_beams, rng, s.range_m)
                       for mode in self._modes()]

    def _modes(self) -> tuple[int, ...]:
        return (0,) if self.single_ramp else (1, 2)

    def _beat_hz(self, e: Echoes, mode: int) -> np.ndarray:
        """Beat frequency of each echo in a ramp (``mode`` as :meth:`_prepare`); bin k holds
        range_offset_m + k range_per_bin_m (RadarConfig.range_of_bin_m)."""
        f_r, f_d = beat_frequencies_hz(e.range_m - self.config.range_offset_m, e.radial_mps, self.config)
        return f_r + 2.0 * f_d if mode == 0 else f_r + f_d if mode == 1 else f_r - f_d

    def synthesize(self, e: Echoes | list[Echoes], draws: list, n_beams: int, pool=None) -> tuple[np.ndarray,
                                                                                                 np.ndarray]:
        """:meth:`spectra` once :meth:`draw` has culled the echoes (or their parts, read in order: never
        concatenated) and drawn; per ramp, one compiled pass gives each echo its beat frequency, phase and kernel values
        (:meth:`_prepare`), then the grid, IFFT and spectrum. With a ``pool``, the down ramp runs there
        beside the up ramp."""
        if self.single_ramp:
            return self._ramp(e, 0, n_beams, draws[0]), np.zeros((n_beams, 0), np.float32)
        if pool is None:
            return self._ramp(e, 1, n_beams, draws[0]), self._ramp(e, 2, n_beams, draws[1])
        down = pool.submit(self._ramp, e, 2, n_beams, draws[1])
        return self._ramp(e, 1, n_beams, draws[0]), down.result()

    def _prepare(self, e: Echoes | list[Echoes], mode: int):
        """(f of every echo, then the kernel exponents, grid indices, phases and amplitudes of
        those in the band) of one ramp: ``mode`` 0 single ramp, 1 up, 2 down (:func:`.synth_kernels.ramp_echoes`).
        ``e`` may be the parts of the echoes: the same as on their concatenation, without it."""
        from . import synth_kernels  # numba: compiled (cached) at the first call, not at import

        parts = [e] if isinstance(e, Echoes) else e
        n = sum(len(q.beam) for q in parts)
        f_all, arg = np.empty(n), np.empty((n, _KERNEL_WIDTH), np.float32)
        base, ph32, amp32 = np.empty(n, np.intp), np.empty(n, np.float32), np.empty(n, np.float32)
        c = self.config
        m_grid = self.n_grid
        i = m = 0
        for q in parts:
            m = synth_kernels.ramp_echoes(
                np.ascontiguousarray(q.beam), *(np.ascontiguousarray(a, float) for a in (
                    q.range_m, q.radial_mps, q.power_w, q.phase_rad)),
                mode, 4.0 * c.bandwidth_hz * c.modulation_hz / SPEED_OF_LIGHT_MPS, c.range_offset_m,
                2.0 * c.f0_hz / SPEED_OF_LIGHT_MPS, 0.5 * self.ramp_s, 4.0 * math.pi / self.lambda_m, 0.5 * self.fs_hz,
                m_grid / self.fs_hz, float(m_grid), m_grid + _KERNEL_WIDTH - 1, self._offsets, self._u_scale,
                np.float32(_KERNEL_BETA), f_all, arg, base, ph32, amp32, i, m)
            i += len(q.beam)
        return f_all, arg[:m], base[:m], ph32[:m], amp32[:m]

    def _ramp(self, e: Echoes | list[Echoes], mode: int, n_beams: int, draws) -> np.ndarray:
        """Power spectra of one ramp (``mode`` as :meth:`_prepare`) of the echoes ``e`` with its ``draws``:
        spread, IFFT, noise, window, FFT, then the phase-noise skirts of the strong echoes (:mod:`.receiver`)."""
        z = self._grid(*self._prepare(e, mode)[1:], n_beams)
        return self._spectrum_of_grid(z, *draws)

    def _spectrum_of_grid(self, z, noise, skirts) -> np.ndarray:
        """The power spectrum (:meth:`power_spectrum`) of the signal ``z[:, time_index] * deapodize`` from
        :meth:`_grid`'s IFFT plus the ``noise``, then the ``skirts`` added, in compiled passes with numpy's
        arithmetic (complex times real, noise, window; the bins' powers)."""
        from . import synth_kernels  # numba: compiled (cached) at the first call, not at import

        empty = np.zeros((0, 0))
        s = synth_kernels.windowed_samples(z, self._time_index, self._deapodize, empty if noise is None else noise,
                                     self.window)
        x = scipy.fft.rfft(s, n=self.n_fft, axis=1)
        return synth_kernels.bin_powers(x, self.config.n_bins, self._scale,
                                  np.zeros((0, 0), np.float32) if skirts is None else skirts)
