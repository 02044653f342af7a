"""Proprioceptive sensor models: odometer, gyro and RTK-GPS truth.

Each sensor samples a :class:`~impala_radar.simulator.vehicle.Trajectory` at integer-ns times
that are exact multiples of its period (``round(1e9 / rate_hz)`` ns), in ``[start_ns,
end_ns)``, and draws all its randomness from the ``numpy.random.Generator`` it is given,
so a seed reproduces a mission. ``samples`` yields ``(t_ns, msg)`` in time order.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

import impala_msgs
from impala_flow import msgs

from .vehicle import Trajectory

__all__ = ["Odometer", "Gyro", "Gps", "make_sensors", "sample_times_ns"]


def sample_times_ns(rate_hz: float, start_ns: int, end_ns: int) -> np.ndarray:
    """Multiples of the period ``round(1e9 / rate_hz)`` ns in ``[start_ns, end_ns)``."""
    if rate_hz <= 0:
        raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
    period = int(round(1e9 / rate_hz))
    first = -(-int(start_ns) // period)  # ceil division on integers
    last = -(-int(end_ns) // period)
    return np.arange(first, last, dtype=np.int64) * period


@dataclass
class Odometer:
    """Wheel odometer: forward speed with scale error, white noise and slip bursts.

    Measured speed = (1 + scale_error) * slip(t) * v + n, n ~ N(0, noise_mps) while the
    vehicle moves (an encoder at standstill reads exactly 0). Slip bursts start as a Poisson
    process of ``slip_rate_per_s`` and last ``slip_duration_s``; during one the reading is
    multiplied by ``slip_factor`` (> 1 wheel spin, < 1 skid).
    """

    rate_hz: float = 50.0
    scale_error: float = 0.01
    noise_mps: float = 0.02
    slip_rate_per_s: float = 0.01
    slip_duration_s: float = 0.5
    slip_factor: float = 1.2

    port: ClassVar[str] = "odometer"
    msg_type: ClassVar[type] = impala_msgs.Speed

    def slip_mask(self, t_ns: np.ndarray, rng: np.random.Generator, start_ns: int,
                  end_ns: int) -> np.ndarray:
        """True where a slip burst is active (bursts drawn over ``[start_ns, end_ns)``)."""
        duration_s = (end_ns - start_ns) * 1e-9
        n = rng.poisson(self.slip_rate_per_s * max(duration_s, 0.0))
        starts = np.sort(start_ns + rng.uniform(0.0, duration_s, n) * 1e9)
        ends = starts + self.slip_duration_s * 1e9
        # a sample slips if the latest burst started before it has not ended yet
        k = np.searchsorted(starts, t_ns, side="right") - 1
        covered_end = np.maximum.accumulate(ends)[np.maximum(k, 0)] if n else np.zeros(len(t_ns))
        return (k >= 0) & (t_ns < covered_end)

    def samples(self, trajectory: Trajectory, rng: np.random.Generator, start_ns: int,
                end_ns: int) -> Iterator[tuple[int, impala_msgs.Speed]]:
        t = sample_times_ns(self.rate_hz, start_ns, end_ns)
        v, _ = trajectory.velocity(t)
        slip = np.where(self.slip_mask(t, rng, start_ns, end_ns), self.slip_factor, 1.0)
        noise = rng.normal(0.0, self.noise_mps, len(t)) * (v != 0.0)
        measured = (1.0 + self.scale_error) * slip * v + noise
        for ti, m in zip(t.tolist(), measured.tolist(), strict=True):
            yield ti, impala_msgs.Speed(m)


@dataclass
class Gyro:
    """Yaw-rate gyro: rate + bias(t) + white noise; bias(t) = bias_radps + random walk
    of ``bias_walk_radps_per_sqrt_s`` (std of the bias after 1 s)."""

    rate_hz: float = 100.0
    bias_radps: float = 0.002
    noise_radps: float = 0.002
    bias_walk_radps_per_sqrt_s: float = 1e-4

    port: ClassVar[str] = "gyro"
    msg_type: ClassVar[type] = impala_msgs.YawRate

    def samples(self, trajectory: Trajectory, rng: np.random.Generator, start_ns: int,
                end_ns: int) -> Iterator[tuple[int, impala_msgs.YawRate]]:
        t = sample_times_ns(self.rate_hz, start_ns, end_ns)
        _, w = trajectory.velocity(t)
        dt_s = 1.0 / self.rate_hz
        steps = rng.normal(0.0, self.bias_walk_radps_per_sqrt_s * np.sqrt(dt_s), len(t))
        steps[:1] = 0.0  # the bias is exactly bias_radps at the first sample
        bias = self.bias_radps + np.cumsum(steps)
        measured = w + bias + rng.normal(0.0, self.noise_radps, len(t))
        for ti, m in zip(t.tolist(), measured.tolist(), strict=True):
            yield ti, impala_msgs.YawRate(m)


@dataclass
class Gps:
    """RTK-GPS truth: position + N(0, sigma_m) per axis, heading from the trajectory
    (+ N(0, sigma_theta_rad), 0 by default), ``cov_xyt`` = diag(sigma^2, sigma^2,
    sigma_theta^2), frame ``map``."""

    rate_hz: float = 10.0
    sigma_m: float = 0.02
    sigma_theta_rad: float = 0.0

    port: ClassVar[str] = "gps"
    msg_type: ClassVar[type] = msgs.Pose2D

    def samples(self, trajectory: Trajectory, rng: np.random.Generator, start_ns: int,
                end_ns: int) -> Iterator[tuple[int, msgs.Pose2D]]:
        t = sample_times_ns(self.rate_hz, start_ns, end_ns)
        xyt = trajectory.pose(t)
        xyt[:, :2] += rng.normal(0.0, self.sigma_m, (len(t), 2))
        xyt[:, 2] += rng.normal(0.0, self.sigma_theta_rad, len(t))
        cov = np.diag([self.sigma_m**2, self.sigma_m**2, self.sigma_theta_rad**2])
        for ti, (x, y, th) in zip(t.tolist(), xyt.tolist(), strict=True):
            yield ti, msgs.Pose2D(x, y, msgs.wrap_angle(th), cov.copy(), "map")


SENSOR_TYPES: dict[str, type] = {"odometer": Odometer, "gyro": Gyro, "gps": Gps}


def make_sensors(spec: dict[str, dict[str, Any] | None]) -> dict[str, Any]:
    """Build sensors from ``{"odometer": {...}, "gyro": {...}, "gps": {...}}`` (a ``None``
    or empty dict takes the defaults). Keys of the result are the port names. Unknown
    sensors or parameters raise ``ValueError`` naming the key."""
    sensors: dict[str, Any] = {}
    for name, params in spec.items():
        cls = SENSOR_TYPES.get(name)
        if cls is None:
            raise ValueError(f"unknown sensor {name!r} (known: {', '.join(SENSOR_TYPES)})")
        params = dict(params or {})
        known = {f.name for f in dataclasses.fields(cls)}
        for key in params:
            if key not in known:
                raise ValueError(f"unknown parameter {key!r} for sensor {name!r} "
                                 f"(known: {', '.join(sorted(known))})")
        sensors[name] = cls(**params)
    return sensors
