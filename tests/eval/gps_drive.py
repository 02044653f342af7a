"""A synthetic drive seen as a real GPS sees it (20 Hz fixes, each written twice, correlated
noise, a hole in the log, heading = course over ground while moving and unknown at rest,
``cov_xyt[2, 2] = HEADING_UNKNOWN_VAR_RAD2``) and a 4 Hz estimate that drifts, for the
evaluator's tests."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from impala_flow.msgs import HEADING_UNKNOWN_VAR_RAD2, Pose2D

T0_NS = 1_549_986_548_010_563_645  # a RADIATE-like epoch stamp
GPS_PERIOD_NS = 50_000_000  # 20 Hz
EST_EVERY = 5  # the estimate at 4 Hz: every 5th truth time


@dataclass
class Drive:
    t_ns: np.ndarray  # 20 Hz
    xyt: np.ndarray  # the true (smooth) poses
    speed_mps: np.ndarray


def drive(rest_start_s: float = 10.0, stop_at_s: float = 70.0, stop_s: float = 6.0, duration_s: float = 150.0,
          cruise_mps: float = 8.0, straight: bool = False) -> Drive:
    """A drive starting and stopping at rest: 1.5 m/s^2 up to ``cruise_mps``, winding (a
    curvature of period 300 m) unless ``straight``; about 1 km with the defaults."""
    n = int(round(duration_s * 1e9 / GPS_PERIOD_NS)) + 1
    t_s = np.arange(n) * GPS_PERIOD_NS * 1e-9
    a = 1.5

    def ramp(t0: float) -> np.ndarray:  # speed of a start from rest at t0
        return np.clip(a * (t_s - t0), 0.0, cruise_mps)

    stop_end = stop_at_s + stop_s
    brake_from = stop_at_s - cruise_mps / a
    v = np.where(t_s < brake_from, ramp(rest_start_s), np.clip(a * (stop_at_s - t_s), 0.0, cruise_mps))
    v = np.where(t_s >= stop_end, ramp(stop_end), v)
    ds = np.concatenate([[0.0], 0.5 * (v[1:] + v[:-1]) * np.diff(t_s)])
    s = np.cumsum(ds)
    kappa = np.zeros(n) if straight else 0.012 * np.sin(2 * np.pi * s / 300.0)
    th = np.cumsum(kappa * ds) + 0.3
    x = np.cumsum(np.cos(th) * ds)
    y = np.cumsum(np.sin(th) * ds)
    return Drive(T0_NS + np.arange(n, dtype=np.int64) * GPS_PERIOD_NS, np.column_stack([x, y, th]), v)


def gps(d: Drive, seed: int = 0, noise_m: float = 0.15, hole_s: tuple[float, float] | None = (100.0, 102.0),
        moving_mps: float = 1.0, repeat: bool = True, known: bool | None = None, white_m: float = 0.02,
        heading_noise_deg: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """GPS fixes of the drive: (t_ns, xyt, heading known). Position noise: a first-order
    Gauss-Markov process (std ``noise_m``, 10 s correlation) plus ``white_m`` white; heading:
    course over ground (+ ``heading_noise_deg`` noise) above ``moving_mps``, else unknown (placeholder 0).
    ``known``: force every heading known (True) or unknown (False). No fix inside ``hole_s``
    (seconds from the start); with ``repeat`` every fix is written twice (same stamp)."""
    rng = np.random.default_rng(seed)
    n = len(d.t_ns)
    phi = math.exp(-GPS_PERIOD_NS * 1e-9 / 10.0)
    drive_noise = rng.normal(0.0, noise_m * math.sqrt(1 - phi ** 2), (n, 2))
    start = rng.normal(0.0, noise_m, 2)
    gm = lfilter([1.0], [1.0, -phi], drive_noise, axis=0) + start * phi ** np.arange(n)[:, None]
    xy = d.xyt[:, :2] + gm + rng.normal(0.0, white_m, (n, 2))
    is_known = d.speed_mps > moving_mps if known is None else np.full(n, bool(known))
    th = np.where(is_known, d.xyt[:, 2] + np.radians(rng.normal(0.0, heading_noise_deg, n)), 0.0)
    keep = np.ones(n, bool)
    if hole_s is not None:
        rel = (d.t_ns - d.t_ns[0]) * 1e-9
        keep = ~((rel > hole_s[0]) & (rel < hole_s[1]))
    t, xyt, is_known = d.t_ns[keep], np.column_stack([xy, th])[keep], is_known[keep]
    if repeat:
        t, xyt, is_known = np.repeat(t, 2), np.repeat(xyt, 2, axis=0), np.repeat(is_known, 2)
    return t, xyt, is_known


def truth_poses(t_ns: np.ndarray, xyt: np.ndarray, known: np.ndarray) -> list[tuple[int, Pose2D]]:
    """The fixes as the import writes them: heading variance (1 deg)^2 or 'unknown'."""
    out = []
    for t, (x, y, th), k in zip(t_ns.tolist(), xyt.tolist(), known.tolist(), strict=True):
        var = math.radians(1.0) ** 2 if k else HEADING_UNKNOWN_VAR_RAD2
        out.append((t, Pose2D(x, y, th, np.diag([0.15 ** 2, 0.15 ** 2, var]), frame="world")))
    return out


def estimate(d: Drive, seed: int = 1, scale: float = 1.01, yaw_per_m: float = 2e-4, noise_m: float = 0.05,
             hole_s: tuple[float, float] | None = (40.0, 41.6), frame: tuple[float, float, float] = (1.0, 50.0, -20.0)
             ) -> tuple[np.ndarray, np.ndarray]:
    """A 4 Hz odometry of the drive (stamps on every 5th GPS time): the true steps scaled by
    ``scale``, turning ``yaw_per_m`` rad per metre too much, in its own frame (a rotation and
    a shift ``frame``), with white position noise; no pose inside ``hole_s``."""
    t, true = d.t_ns[::EST_EVERY], d.xyt[::EST_EVERY]
    c, s = np.cos(true[:-1, 2]), np.sin(true[:-1, 2])
    dx, dy = np.diff(true[:, 0]), np.diff(true[:, 1])
    fwd, left = c * dx + s * dy, -s * dx + c * dy  # body-frame steps
    extra = yaw_per_m * np.hypot(fwd, left)  # the heading error each step adds
    th = true[:, 2] + np.concatenate([[0.0], np.cumsum(extra)])
    mid = th[:-1] + 0.5 * extra  # each step along the chord of its arc (midpoint heading)
    cs, sn = np.cos(mid), np.sin(mid)
    x = true[0, 0] + np.concatenate([[0.0], np.cumsum(scale * (cs * fwd - sn * left))])
    y = true[0, 1] + np.concatenate([[0.0], np.cumsum(scale * (sn * fwd + cs * left))])
    rot, tx, ty = frame
    cr, sr = math.cos(rot), math.sin(rot)
    rng = np.random.default_rng(seed)
    xyt = np.column_stack([cr * x - sr * y + tx, sr * x + cr * y + ty, th + rot])
    xyt[:, :2] += rng.normal(0.0, noise_m, (len(t), 2))
    keep = np.ones(len(t), bool)
    if hole_s is not None:
        rel = (t - t[0]) * 1e-9
        keep = ~((rel > hole_s[0]) & (rel < hole_s[1]))
    return t[keep], xyt[keep]
