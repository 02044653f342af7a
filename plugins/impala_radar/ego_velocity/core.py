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
scatterer z high at slant range R, i.e. at the depression angle el = asin((h - z) / R); its
radial speed is V0 cos(theta - theta0) cos(el), and cos(el) = ground range / slant range (the
simulator's geometry: radial speed = horizontal velocity . horizontal offset / slant range).
Ground clutter (z = 0) carries the factor in full: ignoring it biases V0 low at short range
(4.86 m/s for 5.00 from detections at 3-10 m, IMPALA 1.3 m high). Raised scatterers (posts,
trunks, walls, car bodies near the radar's height) carry a factor of about 1: applying the
ground factor to them biases V0 high just as much (+0.11 m/s at 3-10 m). A detection does not
say which it is, so the fit is a mixture (``target_heights_m``, by default the ground and the
radar's own height): each detection is on one of the heights, unknown, with the factor f_k of
that height, and V0, theta0, the residual sigma and the share of each height are the maximum
likelihood of

    v_i ~ sum_k pi_k N(f_ik (a cos theta_i + b sin theta_i), sigma^2)

by expectation-maximisation (every M-step is a weighted linear least squares, vectorised).
The latent heights are marginalised, not chosen per detection, so the estimate is
consistent (choosing the closer height per detection would bias V0 where the heights differ
by about the noise). Far away the factors all tend to 1 and the choice does not matter; near
the radar (|f_ground - 1| >> sigma) each detection is classified without doubt. Heights in
between (bushes, kerbs) fall between the two and bias V0 by at most their share times half
the factors' gap. A single height gives the plain linear fit; detections nearer than h - z
for some height (no such geometry) are left out. The reported covariance is that of the
final weighted least squares (sigma^2 (A^T W A)^-1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impala_msgs import RadarDetections

__all__ = ["EgoFit", "radial_speed_model_mps", "fit_ego_velocity", "subset", "elevation_factor"]


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
                     target_heights_m=(0.0,), loss: str = "soft_l1", f_scale_mps: float = 0.25,
                     outlier_sigma: float = 3.0, min_gate_mps: float = 0.3,
                     fit_offset: bool = True, max_iterations: int = 50) -> EgoFit | None:
    """Robust fit of V(theta) = V0 cos(theta - theta0) cos(el) to the detections: cos(el) from
    ``range_m`` and each height of ``target_heights_m`` (a mixture when there are several, see
    the module doc; 1 without ``range_m``); None if fewer than 3 usable detections."""
    az = np.asarray(azimuth_rad, float)
    v = np.asarray(radial_mps, float)
    heights = np.atleast_1d(np.asarray(target_heights_m, float))
    if range_m is None:
        fac = np.ones((len(az), 1))
    else:
        fac = np.column_stack([elevation_factor(range_m, radar_height_m - z) for z in heights])
    ok = np.isfinite(az) & np.isfinite(v) & np.all(np.isfinite(fac), axis=1)
    if ok.sum() < 3:
        return None
    fac = np.where(ok[:, None], fac, 0.0)
    trig = np.column_stack([np.cos(az), np.sin(az)]) if fit_offset else np.cos(az)[:, None]
    q = trig.shape[1]
    basis = trig * fac.mean(axis=1)[:, None]  # robust start: the mean factor of the heights

    def resid(p: np.ndarray) -> np.ndarray:
        return basis[ok] @ p - v[ok]

    p0 = np.linalg.lstsq(basis[ok], v[ok], rcond=None)[0]
    from scipy.optimize import least_squares  # here, not at import: 0.3 s paid by every command's start

    p = least_squares(resid, p0, loss=loss, f_scale=f_scale_mps).x
    res = fac * (trig @ p)[:, None] - v[:, None]  # (n, K): residual under each height
    r = res[np.arange(len(v)), np.argmin(np.abs(res), axis=1)]
    scale = 1.4826 * np.median(np.abs(r[ok] - np.median(r[ok])))
    inlier = ok & (np.abs(r) <= max(outlier_sigma * scale, min_gate_mps))
    n_in = int(inlier.sum())
    if n_in < q + 1:
        cov, sigma2 = np.full((q, q), np.nan), float("nan")
    else:
        t_in, f_in, v_in = trig[inlier], fac[inlier], v[inlier]
        k = f_in.shape[1]
        w = np.full((n_in, k), 1.0 / k)
        share = np.full(k, 1.0 / k)
        sigma2 = max(float(np.mean(r[inlier] ** 2)), 1e-12)
        for _ in range(max_iterations if k > 1 else 1):
            if k > 1:  # E-step: posterior of each height per detection
                m = t_in @ p
                logw = np.log(np.maximum(share, 1e-300)) - (v_in[:, None] - f_in * m[:, None]) ** 2 / (2.0 * sigma2)
                w = np.exp(logw - logw.max(axis=1, keepdims=True))
                w /= w.sum(axis=1, keepdims=True)
                share = w.mean(axis=0)
            s_w, t_w = (w * f_in * f_in).sum(axis=1), (w * f_in).sum(axis=1)  # M-step: weighted LS
            a_mat = t_in.T @ (t_in * s_w[:, None])
            p_new = np.linalg.solve(a_mat, t_in.T @ (t_w * v_in))
            res_in = v_in[:, None] - f_in * (t_in @ p_new)[:, None]
            sigma2 = max(float(np.sum(w * res_in**2)) / n_in, 1e-12)
            done = np.max(np.abs(p_new - p)) < 1e-7
            p = p_new
            if done:
                break
        sigma2 *= n_in / max(1, n_in - q)  # unbiased residual variance
        cov = sigma2 * np.linalg.inv(a_mat)
    a = float(p[0])
    b = float(p[1]) if fit_offset else 0.0
    theta0 = float(np.arctan(b / a)) if a != 0.0 else 0.0
    v0 = a / np.cos(theta0)
    g = np.array([np.cos(theta0), np.sin(theta0)])[:q]
    return EgoFit(float(v0), theta0, float(np.sqrt(max(g @ cov @ g, 0.0))), float(np.sqrt(sigma2)), inlier)


def subset(d: RadarDetections, mask: np.ndarray) -> RadarDetections:
    """The detections where ``mask`` is True."""
    return RadarDetections(d.turn, d.t_ns[mask], d.beam[mask], d.azimuth_rad[mask], d.range_m[mask],
                           d.radial_speed_mps[mask], d.amplitude[mask], d.score[mask])
