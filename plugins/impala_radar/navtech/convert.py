"""Navtech FFT samples <-> the project's beams: power scale, azimuth, index in the turn.

* **Power.** 8-bit samples are the radar's log-compressed power, ``db_per_count`` dB per count
  (0.5 for the CTS350-X): linear power ``10^(count x db / 10)``, exactly what the dataset
  readers give for the same pixel (:func:`~impala_radar.datasets.common.counts_to_power`).
  The SDK documents no dB scale for the 16-bit "high precision" samples; they are read as the
  8-bit count with 8 fractional bits (the 8-bit sample is the high byte): ``10^(v / 256 x db / 10)``,
  so a 16-bit stream of the same scan gives the same powers.
* **Azimuth.** The encoder counts turn clockwise seen from above, 0 = forward (Oxford's and
  Boreas' logs, which record the counts): ``azimuth_rad = wrap(radians(azimuth_offset_deg) -
  2 pi count / encoder_size)``, the readers' expression (:func:`~impala_radar.datasets.navtech_png.ccw_azimuth`).
* **Index.** ``count x azimuth_samples // encoder_size``, the SDK clients' azimuth index (the row
  of the readers' scans: Oxford's counts are 13 + 14 k for row k).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from impala_flow import msgs

from ..datasets.common import counts_to_power

__all__ = ["beam_power", "azimuth_of_count", "count_of_azimuth", "counts_of_power", "index_of_count"]

_TWO_PI = 2.0 * np.pi


@functools.lru_cache(maxsize=8)
def _table(db_per_count: float) -> np.ndarray:
    """The 256 powers of the 8-bit counts, each computed by the readers' own function."""
    table = counts_to_power(np.arange(256, dtype=np.float64) / 255.0, db_per_count)
    table.flags.writeable = False
    return table


@functools.lru_cache(maxsize=2)
def _table16(db_per_count: float) -> np.ndarray:
    """The 65536 powers of the 16-bit values (256 KiB): ``10^(v / 256 x db / 10)``."""
    db = np.arange(65536, dtype=np.float64) / 256.0 * db_per_count
    table = np.power(10.0, db / 10.0).astype(np.float32)
    table.flags.writeable = False
    return table


def beam_power(values: np.ndarray, db_per_count: float, high_precision: bool) -> np.ndarray:
    """Linear power (float32) of 8-bit counts or 16-bit values (see the module doc)."""
    if high_precision:
        return _table16(float(db_per_count))[np.asarray(values, np.uint16)]
    return _table(float(db_per_count))[np.asarray(values, np.uint8)]


def counts_of_power(power: np.ndarray, db_per_count: float, high_precision: bool) -> tuple[np.ndarray, int]:
    """The samples that give ``power`` back (the emulator's inverse of :func:`beam_power`):
    ``rint(10 log10(P) / db_per_count)`` (x 256 for 16-bit), exact for every count and value
    (tests/radar/test_navtech_protocol.py), and how many were clipped to the sample range (a
    power below 1 or beyond the top count, or not finite: never from a Navtech scan)."""
    p = np.asarray(power, dtype=np.float32)
    top = 65535.0 if high_precision else 255.0
    scale = np.float32((2560.0 if high_precision else 10.0) / db_per_count)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.rint(np.log10(p) * scale)
    if p.size and 0.0 <= v.min() and v.max() <= top:  # (a NaN fails both)
        return v.astype(np.uint16 if high_precision else np.uint8), 0
    bad = ~((v >= 0.0) & (v <= top))
    v = np.clip(np.nan_to_num(v, nan=0.0, posinf=top, neginf=0.0), 0.0, top)
    return v.astype(np.uint16 if high_precision else np.uint8), int(np.count_nonzero(bad))


def azimuth_of_count(count: int, encoder_size: int, azimuth_offset_deg: float) -> float:
    """Project azimuth (CCW, 0 = forward, wrapped) of a clockwise encoder count."""
    a = float(count) * (_TWO_PI / encoder_size)
    return float(msgs.wrap_angle(float(np.radians(azimuth_offset_deg)) - a))


def count_of_azimuth(azimuth_rad: float, encoder_size: int, azimuth_offset_deg: float = 0.0) -> int:
    """The encoder count nearest to a project azimuth (the emulator's inverse)."""
    turns = (math.radians(azimuth_offset_deg) - float(azimuth_rad)) / _TWO_PI
    return int(round(turns * encoder_size)) % encoder_size


def index_of_count(count: int, azimuth_samples: int, encoder_size: int) -> int:
    return count * azimuth_samples // encoder_size
