"""Azimuth antenna pattern with sidelobes, and the angular window each scatterer needs.

Without sidelobes (``RadarParams.sidelobe_db = None``) the two-way normalised power pattern
is the Gaussian of :mod:`impala_radar.simulator.spectra`. With them, the horizontal aperture of
length L (a slotted waveguide, Navtech; a patch array, IMPALA/K2Pi) has a Hann-on-pedestal
illumination, whose far field is closed-form (u = L sin(theta) / lambda)::

    w(x) = p + (1 - p) cos^2(pi x),   x in [-1/2, 1/2]
    F(u) = p sinc(u) + (1 - p) [sinc(u) / 2 + (sinc(u - 1) + sinc(u + 1)) / 4]
    F(0) = (1 + p) / 2,    one-way power G(u) = (F(u) / F(0))^2,   two-way g2 = G^2

p = 1 is the uniform aperture (first sidelobe -13.26 dB at u = 1.43); p = 0.08 is Hamming
(-42.7 dB). The pedestal p is solved so that the highest sidelobe of G is ``sidelobe_db``
(typical one-way levels: -20 dB for a patch array, -25 dB for a slotted waveguide); u is
scaled so that G's 3 dB full width is the preset's beam width theta_3.

Each scatterer is evaluated only where its echo can matter: within the angle beyond
which g2 stays below ``level`` (:func:`window_rad`, from the pattern's envelope), the level
being the culling threshold over the scatterer's boresight power, floored at
``pattern_cut_db``. Weak clutter is thus evaluated over its main lobe only, strong corners
down to their far sidelobes.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

__all__ = ["aperture_pattern", "pedestal_for_sidelobe", "AzimuthPattern"]

_U_MAX = 12.0  # the pattern is tabulated up to |u| = 12 (about 9 beam widths)


def aperture_pattern(u, pedestal: float):
    """Field pattern F(u) / F(0) of the Hann-on-pedestal illumination (see module doc)."""
    u = np.asarray(u, float)
    f = pedestal * np.sinc(u) + (1.0 - pedestal) * (0.5 * np.sinc(u) + 0.25 * (np.sinc(u - 1.0) + np.sinc(u + 1.0)))
    return f / (0.5 * (1.0 + pedestal))


def _max_sidelobe_db(pedestal: float) -> float:
    """Highest one-way sidelobe (dB): the largest local maximum beyond the main lobe."""
    u = np.linspace(0.0, _U_MAX, 4801)
    g = aperture_pattern(u, pedestal) ** 2
    first_null = int(np.argmax(np.diff(g) > 0))  # the main lobe decreases until its first null
    k = first_null + int(np.argmax(g[first_null:]))
    uu = np.linspace(u[k - 1], u[k + 1], 201)  # refine the peak
    return float(10.0 * np.log10((aperture_pattern(uu, pedestal) ** 2).max()))


@lru_cache(maxsize=16)
def pedestal_for_sidelobe(sidelobe_db: float) -> float:
    """Pedestal p whose highest one-way sidelobe is ``sidelobe_db`` (-42.7 to -13.26 dB)."""
    lo, hi = 0.08, 1.0  # Hamming .. uniform: the highest sidelobe rises monotonically
    if not _max_sidelobe_db(lo) <= sidelobe_db <= _max_sidelobe_db(hi):
        raise ValueError(f"sidelobe_db {sidelobe_db} outside [-42.7, -13.26] dB")
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if _max_sidelobe_db(mid) > sidelobe_db:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


class AzimuthPattern:
    """Two-way azimuth power pattern g2(d_az) of a beam of 3 dB width ``beam_width_rad``."""

    def __init__(self, beam_width_rad: float, sidelobe_db: float | None):
        self.beam_width_rad = beam_width_rad
        self.sidelobe_db = sidelobe_db
        if sidelobe_db is None:
            self.pedestal = None
            x = np.linspace(0.0, 4.0, 4001)  # in beam widths
            g2 = np.exp(-8.0 * math.log(2.0) * x * x)
            self._u_per_rad = 1.0 / beam_width_rad
        else:
            self.pedestal = pedestal_for_sidelobe(float(sidelobe_db))
            u = np.linspace(0.0, 2.0, 200001)
            g = aperture_pattern(u, self.pedestal) ** 2
            u3 = float(u[np.argmax(g <= 0.5)])  # half-power half-width in u
            self._u_per_rad = 2.0 * u3 / beam_width_rad
            x = np.linspace(0.0, _U_MAX, 48001)
            g2 = aperture_pattern(x, self.pedestal) ** 4
        if sidelobe_db is not None:
            g2[-1] = 0.0  # beyond the table: nothing
        self._x, self._g2 = x, g2
        self._inv_step = 1.0 / (x[1] - x[0])
        # envelope: beyond x_env(L), g2 < L everywhere (reverse cumulative maximum)
        self._env = np.maximum.accumulate(g2[::-1])[::-1]
        self._neg_env = -self._env  # ascending: window_rad's search table

    def u(self, d_azimuth_rad):
        """Pattern variable of an azimuth offset (u = L sin / lambda, or beam widths if Gaussian)."""
        return np.abs(d_azimuth_rad) * self._u_per_rad

    def gain2(self, d_azimuth_rad):
        """Two-way normalised power pattern at azimuth offsets (radians)."""
        if self.pedestal is not None and np.ndim(d_azimuth_rad) == 1 and len(d_azimuth_rad) > 64:
            from . import kernels  # numba: compiled (cached) at the first call, not at import

            return kernels.table_gain2(np.ascontiguousarray(d_azimuth_rad, float), self._u_per_rad,
                                       self._inv_step, self._g2)
        x = self.u(d_azimuth_rad)
        if self.pedestal is None:
            return np.exp(-8.0 * math.log(2.0) * x * x)
        # tabulated (step 2.5e-4 in u: linear interpolation error < 1e-6 of the peak)
        pos = np.minimum(x * self._inv_step, len(self._x) - 1.0)
        k = np.minimum(pos.astype(np.intp), len(self._x) - 2)
        frac = pos - k
        return self._g2[k] * (1.0 - frac) + self._g2[k + 1] * frac

    def window_rad(self, level):
        """Largest azimuth offset where g2 can still reach ``level`` (two-way, linear)."""
        level = np.asarray(level, float)
        # _env is non-increasing in x: index of the last x with env >= level
        k = np.searchsorted(self._neg_env, -level, side="right") - 1
        x = np.where(k >= 0, self._x[np.clip(k, 0, len(self._x) - 1)], 0.0)
        return x / self._u_per_rad
