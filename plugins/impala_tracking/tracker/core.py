"""``tracking.Tracker``: multi-target tracking of Doppler movers (seed 1 §4.3.3, Fig. 18).

- State per track ``x = (x, y, vx, vy)``, a constant-velocity Kalman filter
  (``filterpy.kalman.KalmanFilter``) with white-acceleration noise ``q``; every track is
  predicted to each detection's own beam time (a car at 50 km/h moves 14 m in one turn).
- Measurement ``z = (x, y, v_r)``: position and the ground radial speed, the projection of
  the velocity on the line of sight ``u`` from the radar: ``H = [[I2, 0], [0, u^T]]``, linear
  once ``u`` is taken from the measured bearing.
- Association: squared Mahalanobis distance ``d2 = y^T S^-1 y`` on position and Doppler with
  ``S = H P H^T + R`` (both uncertainties), gated at the chi-square quantile ``gate_prob`` (3
  dof), then the global optimum of ``d2 + ln det S`` (``scipy.optimize.linear_sum_assignment``).
- Existence probability (an IPDA-like recursion): ``p <- p_s p`` per turn, then on a
  detection ``p <- p Pd / (p Pd + (1 - p) Pf)`` and on a miss
  ``p <- p (1 - Pd') / (1 - p Pd')``, where ``Pf`` is the probability
  that a false detection falls in the gate and ``Pd'`` is ``Pd`` times the probability that
  the predicted ground radial speed exceeds the detector's blind speed and the target is in
  range: a car crossing tangentially (zero Doppler) is expected to be missed and keeps its
  probability. Confirmed above ``p_confirm``, deleted below ``p_delete`` or when predicted
  out of the radar's range (``max_range_m``).
- New tracks from detections not associated, not inside the gate of an existing track and
  not within ``birth_exclusion_m`` of a confirmed one (its other echoes, ghost pairs):
  velocity along the line of sight from the Doppler, a wide prior across it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..types import MoverDetections

if TYPE_CHECKING:  # filterpy (scipy.stats: 0.85 s) loads at the first track, not at each command's start
    from filterpy.kalman import KalmanFilter

__all__ = ["cv_transition", "cv_noise", "measurement_matrix", "pair_distances", "line_of_sight", "measurement_cov",
           "existence_update", "Track"]


def cv_transition(dt_s) -> np.ndarray:
    """F(dt) of the constant-velocity model, (..., 4, 4)."""
    dt = np.asarray(dt_s, float)
    f = np.broadcast_to(np.eye(4), dt.shape + (4, 4)).copy()
    f[..., 0, 2] = dt
    f[..., 1, 3] = dt
    return f


def cv_noise(dt_s, q_mps2: float) -> np.ndarray:
    """Q(dt) of white acceleration of spectral density q^2 per axis (discrete Wiener), (..., 4, 4)."""
    dt = np.abs(np.asarray(dt_s, float))
    q = np.zeros(dt.shape + (4, 4))
    a, b, c = dt**3 / 3.0, dt**2 / 2.0, dt
    for i in (0, 1):
        q[..., i, i], q[..., i, i + 2], q[..., i + 2, i], q[..., i + 2, i + 2] = a, b, b, c
    return q * q_mps2**2


def measurement_matrix(u: np.ndarray) -> np.ndarray:
    """H (..., 3, 4) for z = (x, y, u . v)."""
    h = np.zeros(u.shape[:-1] + (3, 4))
    h[..., 0, 0] = h[..., 1, 1] = 1.0
    h[..., 2, 2:] = u
    return h


def pair_distances(x: np.ndarray, p: np.ndarray, t_ns: np.ndarray, det: MoverDetections, q_mps2: float
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(d2, ln det S), each (tracks, detections): every track predicted to every detection's time."""
    dt = (det.t_ns[None, :] - t_ns[:, None]) * 1e-9
    f = cv_transition(dt)
    xp = np.einsum("tdij,tj->tdi", f, x)
    pp = np.einsum("tdij,tjk,tdlk->tdil", f, p, f) + cv_noise(dt, q_mps2)
    u = line_of_sight(det)
    h = measurement_matrix(u)
    z = np.column_stack([det.xy_m, det.radial_speed_mps])
    y = z[None] - np.einsum("dij,tdj->tdi", h, xp)
    s = np.einsum("dij,tdjk,dlk->tdil", h, pp, h) + measurement_cov(det)[None]
    _, logdet = np.linalg.slogdet(s)
    d2 = np.einsum("tdi,tdi->td", y, np.linalg.solve(s, y[..., None])[..., 0])
    return d2, logdet


def line_of_sight(det: MoverDetections) -> np.ndarray:
    d = det.xy_m - det.radar_xy_m
    return d / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)[:, None]


def measurement_cov(det: MoverDetections) -> np.ndarray:
    r = np.zeros((len(det.t_ns), 3, 3))
    r[:, :2, :2] = det.cov_xy
    r[:, 2, 2] = det.radial_var
    return r


def existence_update(p: float, detected: bool, pd: float, pf: float) -> float:
    """Bayes update of the existence probability on a detection or a miss (see module doc)."""
    if detected:
        return p * pd / (p * pd + (1.0 - p) * pf)
    return p * (1.0 - pd) / (1.0 - p * pd)


@dataclass
class Track:
    id: int
    kf: KalmanFilter
    t_ns: int
    p: float
    born_turn: int
    confirmed: bool = False
    hits: int = 1
    misses: int = 0
    history: list = field(default_factory=list)
