"""Radar presets: the IMPALA radar (seed 1, Fig. 2) and the K2Pi radar (seed 2).

Triangular ("roof") FMCW modulation, seed 1 eq. (2)-(4)::

    f_b = 4 dF Fm R / c  +-  2 V f0 / c        (f_r +- f_d)
    dR = c / (2 dF)          dV = c Fm / (2 f0)

One modulation period 1/Fm is one up ramp and one down ramp of duration
T = 1 / (2 Fm) each, so the Rayleigh frequency resolution of one ramp is 1/T = 2 Fm.
The presets zero-pad each ramp twice: ``bin_hz = Fm = 1 / (2 T)``, i.e. two spectrum bins
per Rayleigh cell (``range_per_bin_m = dR / 2``), which lets the peak pairer interpolate.
``n_bins`` covers 0..range_max plus a Doppler margin: IMPALA 288 bins = 0..103.7 kHz, i.e.
107.9 m at zero Doppler, the last 7.9 m (7.6 kHz) leaving room for |V| <= 47 m/s at 100 m.

With Fm = 360 Hz and 360 beams per turn at 1 turn/s, one beam is exactly one
modulation period (one up and one down spectrum per degree of antenna rotation).
"""

from __future__ import annotations

import dataclasses
import math

from impala_msgs import SPEED_OF_LIGHT_MPS, RadarConfig

__all__ = ["IMPALA", "K2PI", "NAVTECH", "PRESETS", "preset", "ZERO_PADDING"]

ZERO_PADDING = 2
"""Spectrum bins per Rayleigh frequency cell (1/T) in the presets."""


def _bins_for(bandwidth_hz: float, modulation_hz: float, bin_hz: float, range_m: float,
              doppler_margin_mps: float, f0_hz: float) -> int:
    """Bins covering f_r(range_m) + f_d(margin) (eq. 2), rounded up to a multiple of 16."""
    f_max_hz = (4.0 * bandwidth_hz * modulation_hz * range_m
                + 2.0 * doppler_margin_mps * f0_hz) / SPEED_OF_LIGHT_MPS
    return int(16 * math.ceil(f_max_hz / bin_hz / 16))


# IMPALA radar, seed 1 Fig. 2: 24 GHz, 18 dBm EIRP, 1 turn/s, 3-100 m, 4 deg,
# dR = 0.75 m (dF = 200 MHz), dV = 2.25 m/s (Fm = 360 Hz); 1.3 m high (Beynes).
IMPALA = RadarConfig(
    name="IMPALA",
    f0_hz=24.0e9,
    bandwidth_hz=200.0e6,
    modulation_hz=360.0,
    bin_hz=360.0 * 2 / ZERO_PADDING,
    n_bins=_bins_for(200.0e6, 360.0, 360.0, 100.0, 40.0, 24.0e9),  # 288
    beam_width_rad=math.radians(4.0),
    rotation_hz=1.0,
    beams_per_turn=360,
    range_min_m=3.0,
    range_max_m=100.0,
    doppler=True,
    height_m=1.3,
)

# K2Pi radar, seed 2: 24 GHz, dF = 250 MHz (dR = 0.6 m), 3 deg, 1 Hz, 3-100 m, 3 m high on
# the car. Its modulation rate is not given in the seed; the same Fm = 360 Hz roof law is
# used (one beam per degree), so the chain's Doppler stages also run on it.
K2PI = RadarConfig(
    name="K2Pi",
    f0_hz=24.0e9,
    bandwidth_hz=250.0e6,
    modulation_hz=360.0,
    bin_hz=360.0 * 2 / ZERO_PADDING,
    n_bins=_bins_for(250.0e6, 360.0, 360.0, 100.0, 40.0, 24.0e9),  # 352
    beam_width_rad=math.radians(3.0),
    rotation_hz=1.0,
    beams_per_turn=360,
    range_min_m=3.0,
    range_max_m=100.0,
    doppler=True,
    height_m=3.0,
)

# Navtech CTS350-X, as in Oxford Radar RobotCar (RADAR.md; ../shared/data): 76-77 GHz
# single-ramp (sawtooth) FMCW, power only (no up/down pair), 4 turns/s, 400 azimuths, one
# sweep per azimuth (Fm = 1600 Hz), 3768 range bins of 4.38 cm (measured on the Oxford
# sample against its ground truth: impala_radar.datasets.oxford), bin k at its centre,
# 1.8 deg beam (3 dB, horizontal), clockwise. With dF = 1 GHz the Rayleigh resolution c/(2 dF)
# is 15 cm: the bins oversample it 3.4 times, as the radar's processor does.
_NAVTECH_BIN_M = 0.0438
NAVTECH = RadarConfig(
    name="navtech-cts350x",
    f0_hz=76.5e9,
    bandwidth_hz=1.0e9,
    modulation_hz=1600.0,
    bin_hz=_NAVTECH_BIN_M * 4.0 * 1.0e9 * 1600.0 / SPEED_OF_LIGHT_MPS,
    n_bins=3768,
    beam_width_rad=math.radians(1.8),
    rotation_hz=4.0,
    beams_per_turn=400,
    range_min_m=0.0,
    range_max_m=3768 * _NAVTECH_BIN_M,
    doppler=False,
    height_m=2.0,
    range_offset_m=0.5 * _NAVTECH_BIN_M,
)

PRESETS: dict[str, RadarConfig] = {"impala": IMPALA, "k2pi": K2PI, "navtech": NAVTECH}


def preset(name: str) -> RadarConfig:
    """A copy of the preset called ``name`` (case-insensitive): ``impala``, ``k2pi`` or ``navtech``."""
    try:
        return dataclasses.replace(PRESETS[name.lower()])
    except KeyError:
        valid = ", ".join(sorted(PRESETS))
        raise KeyError(f"unknown radar preset {name!r}; valid presets: {valid}") from None
