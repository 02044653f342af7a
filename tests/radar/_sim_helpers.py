"""Helpers for the simulator tests: an analytic constant-velocity vehicle, peak finding."""

from __future__ import annotations

import numpy as np

from impala_msgs import SPEED_OF_LIGHT_MPS as C


class StraightLine:
    """x = x0 + v t cos(theta), y = y0 + v t sin(theta): exact, for analytic predictions."""

    def __init__(self, x0_m, y0_m, theta_rad, speed_mps, duration_s, start_ns=0):
        self.x0, self.y0, self.theta, self.v = x0_m, y0_m, theta_rad, speed_mps
        self.start_ns = int(start_ns)
        self.end_ns = self.start_ns + int(round(duration_s * 1e9))
        self.length_m = speed_mps * duration_s

    def pose(self, t_ns):
        t = (np.asarray(t_ns, dtype=np.int64) - self.start_ns) * 1e-9
        return np.stack([self.x0 + self.v * t * np.cos(self.theta),
                         self.y0 + self.v * t * np.sin(self.theta),
                         np.full(np.shape(t), self.theta)], axis=-1)

    def velocity(self, t_ns):
        shape = np.shape(t_ns)
        return np.full(shape, float(self.v)), np.zeros(shape)


def peak_bin(power, lo, hi):
    """Sub-bin peak position in [lo, hi): parabolic interpolation on log power."""
    k = lo + int(np.argmax(power[lo:hi]))
    a, b, c = np.log(power[k - 1:k + 2].astype(float))
    return k + 0.5 * (a - c) / (a - 2 * b + c)


def range_velocity(f_up_hz, f_down_hz, config):
    """Seed 1 eq. (3)."""
    r = C / (8 * config.bandwidth_hz * config.modulation_hz) * (f_up_hz + f_down_hz)
    v = C / (4 * config.f0_hz) * (f_up_hz - f_down_hz)
    return r, v


def beat_hz(range_m, radial_mps, config):
    """Seed 1 eq. (2): (f_r, f_d)."""
    return (4 * config.bandwidth_hz * config.modulation_hz * range_m / C,
            2 * radial_mps * config.f0_hz / C)
