"""``radar.EgoVelocity``: vehicle speed from the Doppler of static targets (seed 1 §4.3.1).

For a static target seen at azimuth theta (vehicle frame, 0 = heading, the antenna's
"top nord"), the radial speed is V(theta) = V0 cos(theta) (seed 1 eq. 7), negative ahead
when the vehicle moves forward (eq. 3 sign), so the forward speed is -V0. A mounting or
side-slip angle theta0 generalises it to V0 cos(theta - theta0) = a cos(theta) +
b sin(theta), linear in (a, b): the robust fit is convex (``scipy.optimize.least_squares``
with a ``soft_l1``/``huber`` loss), no RANSAC needed. Then the robust residual scale
(1.4826 MAD) separates the static detections from those off the curve (movers, ghosts),
and an ordinary least-squares fit on the inliers gives V0, theta0 and the covariance.

Elevation (RADAR.md item 3): the radar is ``radar_height_m`` above the ground and sees a
scatterer ``target_height_m`` high at slant range R, i.e. at the depression angle
el = asin((h - z) / R); its radial speed is V0 cos(theta - theta0) cos(el), and
cos(el) = ground range / slant range. Ground clutter (z = 0), which carries most of the
Doppler of a ground vehicle's radar at short range, would otherwise bias V0 low: by 3 %
from detections at 3-10 m with the IMPALA 1.3 m high (4.86 m/s for 5.00). The factor is
applied to each detection's basis (the fit stays linear); detections nearer than h - z
(no such geometry) are left out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from impala_flow.component import Component, Input, Output, Param
from impala_flow.msgs import RadarDetections, Speed

__all__ = ["EgoFit", "radial_speed_model_mps", "fit_ego_velocity", "EgoVelocity", "subset", "elevation_factor"]


def radial_speed_model_mps(azimuth_rad, v0_mps: float, theta0_rad: float = 0.0):
    """Seed 1 eq. (7), with an offset: V(theta) = V0 cos(theta - theta0)."""
    return v0_mps * np.cos(np.asarray(azimuth_rad) - theta0_rad)


@dataclass
class EgoFit:
    v0_mps: float          # amplitude of eq. (7); forward speed = -v0
    theta0_rad: float
    v0_std_mps: float
    residual_std_mps: float
    inlier: np.ndarray     # bool per detection

    @property
    def speed_mps(self) -> float:
        return -self.v0_mps


def elevation_factor(range_m, height_above_target_m: float) -> np.ndarray:
    """cos(el) = sqrt(1 - (dh / R)^2) = ground range / slant range; NaN where R <= |dh|."""
    r = np.asarray(range_m, float)
    s = np.divide(height_above_target_m, r, out=np.full(r.shape, np.inf), where=r > 0)
    return np.sqrt(np.where(np.abs(s) < 1.0, 1.0 - s * s, np.nan))


def fit_ego_velocity(azimuth_rad, radial_mps, *, range_m=None, radar_height_m: float = 0.0,
                     target_height_m: float = 0.0, loss: str = "soft_l1", f_scale_mps: float = 0.25,
                     outlier_sigma: float = 3.0, min_gate_mps: float = 0.3,
                     fit_offset: bool = True) -> EgoFit | None:
    """Robust fit of V(theta) = V0 cos(theta - theta0) cos(el) to the detections (cos(el)
    from ``range_m`` and the heights, see the module doc; 1 without ``range_m``); None if
    fewer than 3 usable detections."""
    az = np.asarray(azimuth_rad, float)
    v = np.asarray(radial_mps, float)
    if range_m is None:
        cos_el = np.ones_like(az)
    else:
        cos_el = elevation_factor(range_m, radar_height_m - target_height_m)
    ok = np.isfinite(az) & np.isfinite(v) & np.isfinite(cos_el)
    if ok.sum() < 3:
        return None
    cos_el = np.where(ok, cos_el, 0.0)
    basis = np.column_stack([np.cos(az), np.sin(az)]) if fit_offset else np.cos(az)[:, None]
    basis = basis * cos_el[:, None]

    def resid(p: np.ndarray) -> np.ndarray:
        return basis[ok] @ p - v[ok]

    p0 = np.linalg.lstsq(basis[ok], v[ok], rcond=None)[0]
    p = least_squares(resid, p0, loss=loss, f_scale=f_scale_mps).x
    r = basis @ p - v
    scale = 1.4826 * np.median(np.abs(r[ok] - np.median(r[ok])))
    inlier = ok & (np.abs(r) <= max(outlier_sigma * scale, min_gate_mps))
    if inlier.sum() >= basis.shape[1] + 1:
        a_in = basis[inlier]
        p, *_ = np.linalg.lstsq(a_in, v[inlier], rcond=None)
        r_in = a_in @ p - v[inlier]
        sigma2 = float(r_in @ r_in) / max(1, len(r_in) - basis.shape[1])
        cov = sigma2 * np.linalg.inv(a_in.T @ a_in)
    else:
        sigma2, cov = float("nan"), np.full((basis.shape[1],) * 2, np.nan)
    a = float(p[0])
    b = float(p[1]) if fit_offset else 0.0
    theta0 = float(np.arctan(b / a)) if a != 0.0 else 0.0
    v0 = a / np.cos(theta0)
    g = np.array([np.cos(theta0), np.sin(theta0)])[: basis.shape[1]]
    return EgoFit(float(v0), theta0, float(np.sqrt(max(g @ cov @ g, 0.0))), float(np.sqrt(sigma2)), inlier)


def subset(d: RadarDetections, mask: np.ndarray) -> RadarDetections:
    """The detections where ``mask`` is True."""
    return RadarDetections(d.turn, d.t_ns[mask], d.beam[mask], d.azimuth_rad[mask], d.range_m[mask],
                           d.radial_speed_mps[mask], d.amplitude[mask], d.score[mask])


class EgoVelocity(Component):
    """Per turn: robust fit of V(theta) = V0 cos(theta - theta0) cos(el) to the detections
    (cos(el) from each detection's slant range and the heights: see the module doc); emits the
    forward speed -V0 with its standard deviation, and the detections off the curve
    (candidate movers). Both stamped with the detections' time (the turn's last beam).
    Turns with fewer than ``min_detections`` finite detections emit nothing (counted)."""

    detections = Input(RadarDetections, doc="paired detections of one turn")
    speed = Output(Speed, doc="forward speed (m/s) and its standard deviation")
    movers = Output(RadarDetections, doc="detections off the static-Doppler curve")

    loss = Param(str, default="soft_l1", choices=("soft_l1", "huber", "cauchy", "arctan"),
                 doc="robust loss of scipy.optimize.least_squares")
    f_scale_mps = Param(float, default=0.25, gt=0, doc="residual scale of the robust loss")
    outlier_sigma = Param(float, default=3.0, gt=0, doc="movers: |residual| > this x robust sigma")
    min_gate_mps = Param(float, default=0.3, ge=0, doc="movers: and |residual| > this")
    min_detections = Param(int, default=10, ge=3, doc="fewer finite detections: no estimate")
    fit_offset = Param(bool, default=True, doc="fit theta0 (mounting / side-slip angle) too")
    radar_height_m = Param(float, default=1.3, ge=0,
                           doc="radar above the ground (IMPALA 1.3 m, K2Pi 3 m): the depression angle of the echoes")
    target_height_m = Param(float, default=0.0, ge=0,
                            doc="height assumed for the scatterers (0: ground clutter, which dominates)")
    std_floor_mps = Param(float, default=0.005, ge=0,
                          doc="added in quadrature to the formal std (peak-interpolation bias: -3 mm/s measured)")

    def start(self) -> None:
        self.last_fit: EgoFit | None = None
        self.estimates = 0
        self.skipped = 0

    def process(self, t: int) -> None:
        d: RadarDetections = self.detections.take()
        if np.isfinite(d.radial_speed_mps).sum() < self.min_detections:
            self.skipped += 1
            return
        fit = fit_ego_velocity(d.azimuth_rad, d.radial_speed_mps, range_m=d.range_m,
                               radar_height_m=self.radar_height_m, target_height_m=self.target_height_m, loss=self.loss,
                               f_scale_mps=self.f_scale_mps, outlier_sigma=self.outlier_sigma,
                               min_gate_mps=self.min_gate_mps, fit_offset=self.fit_offset)
        if fit is None:
            self.skipped += 1
            return
        self.last_fit = fit
        self.estimates += 1
        self.speed.emit(t, Speed(fit.speed_mps, float(np.hypot(fit.v0_std_mps, self.std_floor_mps))))
        self.movers.emit(t, subset(d, ~fit.inlier & np.isfinite(d.radial_speed_mps)))

    def summary(self) -> dict:
        return {"estimates": self.estimates, "skipped": self.skipped}
