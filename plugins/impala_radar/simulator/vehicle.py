"""Smooth, curvature-limited planar vehicle trajectories.

A :class:`Trajectory` is built in three steps by :meth:`Trajectory.from_waypoints`:

1. **Path.** The waypoint polyline is densified and fitted with a parametric smoothing
   spline (``scipy.interpolate.splprep``, periodic for closed loops). The smoothing
   factor is the smallest (found by bisection) for which the path curvature stays below
   ``max_curvature_1pm``, so sharp corners are rounded and straight legs stay straight.
   If no smoothing meets the limit (waypoints too tight for it), the curvature profile is
   spread along the path (Gaussian, which keeps each turn's angle) and clipped, and the
   heading and position re-integrated from it: the path then drifts from the later
   waypoints and a closed loop may not close exactly. Give turns room for 1/kappa_max.
   The path is resampled uniformly in arc length.
2. **Speed profile.** The target speed (one per waypoint, linear in arc length between
   them) is capped where the lateral acceleration ``v^2 |kappa|`` would exceed
   ``max_lateral_accel_mps2``, then limited to ``|dv/dt| <= max_accel_mps2`` by a
   forward and a backward pass (exact, vectorised with ``np.minimum.accumulate`` on
   ``v^2``). By default the vehicle starts and ends at rest.
3. **Time.** The path is a chain of 5 cm circular arcs (curvature constant on each) and
   the acceleration is constant on each arc, so ``s(t)``, speed, heading and position
   have closed forms at any integer-ns time: :meth:`Trajectory.pose` is exactly the
   integral of :meth:`Trajectory.velocity`, with no interpolation error.

Frame: x, y in metres in the world frame, theta the heading (counter-clockwise from x).
Outside ``[start_ns, end_ns]`` the pose is held and the velocity is zero.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import splev, splprep
from scipy.ndimage import gaussian_filter1d

from impala_flow.msgs import wrap_angle as _wrap

__all__ = ["Trajectory"]

_DS_M = 0.05  # arc-length step of the path samples
_CURVATURE_MARGIN = 0.98  # smoothing aims below the limit by this factor


def _densify(points: np.ndarray, spacing_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Polyline resampled every ~``spacing_m`` keeping the vertices; also their indices."""
    seg = np.diff(points, axis=0)
    n_per = np.maximum(1, np.ceil(np.hypot(seg[:, 0], seg[:, 1]) / spacing_m).astype(int))
    frac = np.concatenate([np.arange(n) / n for n in n_per])
    start = np.repeat(np.arange(len(seg)), n_per)
    dense = np.vstack([points[start] + frac[:, None] * seg[start], points[-1:]])
    vertex_idx = np.concatenate([[0], np.cumsum(n_per)])
    return dense, vertex_idx


class _Path:
    """Arc-length sampled planar path: s, x, y, theta (unwrapped), curvature."""

    def __init__(self, tck: tuple, u_end: float, clip_curvature: float | None,
                 closed: bool) -> None:
        u_fine = np.linspace(0.0, u_end, max(2000, int(u_end / (0.4 * _DS_M))))
        xf, yf = splev(u_fine, tck)
        s_fine = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(xf), np.diff(yf)))])
        self.length_m = float(s_fine[-1])
        n = max(2, int(math.ceil(self.length_m / _DS_M)) + 1)
        self.s_m = np.linspace(0.0, self.length_m, n)
        self.u = np.interp(self.s_m, s_fine, u_fine)
        self._s_fine, self._u_fine = s_fine, u_fine
        x, y = splev(self.u, tck)
        dx, dy = splev(self.u, tck, der=1)
        ddx, ddy = splev(self.u, tck, der=2)
        theta = np.unwrap(np.arctan2(dy, dx))
        kappa = (dx * ddy - dy * ddx) / np.maximum(np.hypot(dx, dy), 1e-12) ** 3
        ds = self.s_m[1] - self.s_m[0]
        if clip_curvature is not None and np.max(np.abs(kappa)) > clip_curvature:
            kappa = _spread_curvature(kappa, clip_curvature, ds, closed)
            dtheta = 0.5 * (kappa[1:] + kappa[:-1]) * ds
            theta = theta[0] + np.concatenate([[0.0], np.cumsum(dtheta)])
        # The path is a chain of circular arcs, one per step (heading linear in s), so
        # positions, heading and curvature agree exactly at every s, not only at the nodes.
        self.theta = theta
        self.step_kappa = np.diff(theta) / ds
        dxy = _arc_displacement(theta[:-1], self.step_kappa, np.full(n - 1, ds))
        self.x = x[0] + np.concatenate([[0.0], np.cumsum(dxy[0])])
        self.y = y[0] + np.concatenate([[0.0], np.cumsum(dxy[1])])
        self.ds_m = ds
        # largest curvature touching each node (for the lateral-acceleration cap)
        k_abs = np.abs(self.step_kappa)
        self.node_kappa = np.maximum(np.append(k_abs, k_abs[-1]), np.insert(k_abs, 0, k_abs[0]))

    def at(self, s_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """x, y, theta (unwrapped), curvature at arc lengths ``s_m`` (exact on the arcs)."""
        i = np.clip((s_m / self.ds_m).astype(np.int64), 0, len(self.step_kappa) - 1)
        sigma = s_m - self.s_m[i]
        k = self.step_kappa[i]
        dx, dy = _arc_displacement(self.theta[i], k, sigma)
        return self.x[i] + dx, self.y[i] + dy, self.theta[i] + k * sigma, k

    def s_of_u(self, u: np.ndarray) -> np.ndarray:
        return np.interp(u, self._u_fine, self._s_fine)


def _arc_displacement(theta0: np.ndarray, kappa: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Displacement (2, N) along circular arcs of curvature ``kappa`` and length ``sigma``."""
    half = 0.5 * kappa * sigma
    chord = sigma * np.sinc(half / np.pi)  # np.sinc(z) = sin(pi z) / (pi z)
    return np.array([chord * np.cos(theta0 + half), chord * np.sin(theta0 + half)])


def _spread_curvature(kappa: np.ndarray, limit: float, ds_m: float, closed: bool) -> np.ndarray:
    """Gaussian-spread the curvature (keeps each turn's total angle) until it meets the
    limit, then clip what is left."""
    mode = "wrap" if closed else "nearest"
    sigma_m = 0.5 / limit
    for _ in range(12):
        smooth = gaussian_filter1d(kappa, sigma_m / ds_m, mode=mode)
        if np.max(np.abs(smooth)) <= limit:
            return smooth
        sigma_m *= 1.5
    return np.clip(smooth, -limit, limit)


def _max_curvature(tck: tuple, u_end: float) -> float:
    """Largest |curvature| of the spline; inf if it has a cusp (degenerate fit)."""
    u = np.linspace(0.0, u_end, max(2000, int(u_end / _DS_M)))
    dx, dy = splev(u, tck, der=1)
    ddx, ddy = splev(u, tck, der=2)
    speed = np.hypot(dx, dy)
    if speed.min() <= 0.3 * np.median(speed):  # u is chord length: |dr/du| stays near 1
        return math.inf
    kappa = (dx * ddy - dy * ddx) / speed**3
    return float(np.max(np.abs(kappa)))


def _fit_path(points: np.ndarray, closed: bool, max_curvature: float) -> tuple[tuple, float, bool]:
    """Smoothing spline through the densified polyline: (tck, u_end, meets_limit)."""
    dense, _ = _densify(points, min(1.0, 0.25 / max_curvature))
    u = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(dense, axis=0).T))])
    k = min(3, len(dense) - 1)
    target = _CURVATURE_MARGIN * max_curvature

    def fit(rms_m: float) -> tuple[tuple, float]:
        tck = splprep(dense.T, u=u, k=k, s=len(dense) * rms_m**2, per=int(closed),
                      quiet=1, full_output=1)[0][0]
        return tck, _max_curvature(tck, u[-1])

    lo, hi = 1e-4, None
    best = fit(lo)
    if best[1] <= target:
        return best[0], float(u[-1]), True
    rms = lo
    while rms < 2.0 / max_curvature:  # grow the smoothing until the limit is met
        rms *= 2.0
        cand = fit(rms)
        if cand[1] < best[1]:
            best = cand
        if cand[1] <= target:
            hi = (rms, cand)
            lo = rms / 2.0
            break
    if hi is None:
        return best[0], float(u[-1]), False
    for _ in range(10):  # bisect (in log) for the least smoothing that meets the limit
        mid = math.sqrt(lo * hi[0])
        cand = fit(mid)
        if cand[1] <= target:
            hi = (mid, cand)
        else:
            lo = mid
    return hi[1][0], float(u[-1]), True


def _speed_profile(v_cap: np.ndarray, ds_m: float, accel: float, v0: float,
                   v1: float) -> np.ndarray:
    """Largest v(s) <= v_cap with |d(v^2)/ds| <= 2 accel, v(0) <= v0, v(end) <= v1."""
    s = np.arange(len(v_cap)) * ds_m
    v2 = np.asarray(v_cap, dtype=float) ** 2
    v2[0] = min(v2[0], v0**2)
    v2[-1] = min(v2[-1], v1**2)
    v2 = np.minimum(v2, np.minimum.accumulate(v2 - 2 * accel * s) + 2 * accel * s)
    back = (v2 + 2 * accel * s)[::-1]
    v2 = np.minimum(v2, np.minimum.accumulate(back)[::-1] - 2 * accel * s)
    return np.sqrt(np.maximum(v2, 0.0))


class Trajectory:
    """A time-parametrised planar trajectory, exact at every integer-ns time.

    Internally a chain of steps; on step ``i`` the curvature ``kappa_i`` and the
    acceleration ``a_i`` are constant, so the arc length, speed, heading and position have
    closed forms and :meth:`pose` is exactly the integral of :meth:`velocity`. Build one
    with :meth:`from_waypoints` or :meth:`stationary`. ``start_ns``/``end_ns`` are
    integer nanoseconds on the mission clock; ``length_m`` is the path length.
    """

    def __init__(self, start_ns: int, end_ns: int, t_node_s: np.ndarray, s_node_m: np.ndarray,
                 xyt_node: np.ndarray, v_node_mps: np.ndarray, step_kappa_1pm: np.ndarray) -> None:
        """Low-level constructor from the step chain: node times (s, from ``start_ns``),
        arc lengths, poses (theta unwrapped) and speeds (n nodes), step curvatures (n - 1).
        Prefer the class-method builders."""
        self.start_ns = int(start_ns)
        self.end_ns = int(end_ns)
        self._t = np.asarray(t_node_s, dtype=float)
        self._s = np.asarray(s_node_m, dtype=float)
        self._xyt = np.asarray(xyt_node, dtype=float)
        self._v = np.asarray(v_node_mps, dtype=float)
        self._k = np.asarray(step_kappa_1pm, dtype=float)
        dt = np.diff(self._t)
        self._a = np.divide(np.diff(self._v), dt, out=np.zeros_like(dt), where=dt > 0)
        self._t_end_s = min((self.end_ns - self.start_ns) * 1e-9, float(self._t[-1]))
        self.length_m = float(self._state(np.asarray(self.end_ns))[3])

    # --- builders ---------------------------------------------------------------------

    @classmethod
    def from_waypoints(cls, waypoints_xy_m: np.ndarray, speed_mps: float | np.ndarray, *,
                       max_curvature_1pm: float = 0.2, max_accel_mps2: float = 1.0,
                       start_t_ns: int = 0, closed: bool = False,
                       max_lateral_accel_mps2: float = 2.0,
                       rest_at_ends: bool = True) -> Trajectory:
        """Smooth trajectory through ``waypoints_xy_m`` (N x 2) at ``speed_mps``.

        ``speed_mps`` is one target speed or one per waypoint (linear in between; > 0).
        ``closed`` loops back to the first waypoint (periodic spline). ``rest_at_ends``
        starts and ends at standstill; otherwise at the (capped) target speed.
        """
        pts = np.asarray(waypoints_xy_m, dtype=float).reshape(-1, 2)
        speeds = np.broadcast_to(np.asarray(speed_mps, dtype=float), (len(pts),)).copy()
        if closed and len(pts) > 2 and np.allclose(pts[0], pts[-1]):
            pts, speeds = pts[:-1], speeds[:-1]
        keep = np.concatenate([[True], np.hypot(*np.diff(pts, axis=0).T) > 1e-9])
        pts, speeds = pts[keep], speeds[keep]
        if len(pts) < 2:
            raise ValueError("from_waypoints needs at least two distinct waypoints")
        if np.any(speeds <= 0.0):
            raise ValueError("from_waypoints: speed_mps must be > 0 at every waypoint")
        if max_curvature_1pm <= 0 or max_accel_mps2 <= 0 or max_lateral_accel_mps2 <= 0:
            raise ValueError("from_waypoints: curvature and acceleration limits must be > 0")
        if closed:
            pts = np.vstack([pts, pts[:1]])
            speeds = np.append(speeds, speeds[0])

        tck, u_end, ok = _fit_path(pts, closed, max_curvature_1pm)
        path = _Path(tck, u_end, None if ok else max_curvature_1pm, closed)
        # waypoint i sits at chord parameter u_i of the densified polyline (u is chord length)
        u_way = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
        u_way *= u_end / u_way[-1]
        v_target = np.interp(path.s_m, path.s_of_u(u_way), speeds)
        v_lat = np.sqrt(max_lateral_accel_mps2 / np.maximum(path.node_kappa, 1e-12))
        ends = (0.0, 0.0) if rest_at_ends else (np.inf, np.inf)
        v = _speed_profile(np.minimum(v_target, v_lat), path.ds_m, max_accel_mps2, *ends)
        # constant acceleration on each step: dt = 2 ds / (v_i + v_i+1)
        t_node = np.concatenate([[0.0], np.cumsum(2.0 * path.ds_m / (v[1:] + v[:-1]))])
        xyt = np.column_stack([path.x, path.y, path.theta])
        end = int(start_t_ns) + int(round(t_node[-1] * 1e9))
        return cls(start_t_ns, end, t_node, path.s_m, xyt, v, path.step_kappa)

    @classmethod
    def stationary(cls, x_m: float, y_m: float, theta_rad: float, duration_s: float,
                   start_t_ns: int = 0) -> Trajectory:
        """A vehicle standing still at (x, y, theta) for ``duration_s``."""
        end = int(start_t_ns) + int(round(duration_s * 1e9))
        xyt = np.tile([x_m, y_m, theta_rad], (2, 1))
        return cls(start_t_ns, end, [0.0, duration_s], [0.0, 0.0], xyt, [0.0, 0.0], [0.0])

    # --- queries ----------------------------------------------------------------------

    def _state(self, t_ns: np.ndarray | int) -> np.ndarray:
        """(..., 6): x, y, theta (unwrapped), s, speed, yaw rate; held outside the span."""
        t = np.asarray(t_ns)
        if not np.issubdtype(t.dtype, np.integer):
            t = np.round(t).astype(np.int64)
        inside = (t >= self.start_ns) & (t <= self.end_ns)
        rel = np.clip((t.astype(np.int64) - self.start_ns) * 1e-9, 0.0, self._t_end_s)
        i = np.clip(np.searchsorted(self._t, rel, side="right") - 1, 0, len(self._k) - 1)
        tau = rel - self._t[i]
        v = self._v[i] + self._a[i] * tau
        travelled = self._v[i] * tau + 0.5 * self._a[i] * tau**2
        sigma = np.minimum(travelled, self._s[i + 1] - self._s[i])
        k = self._k[i]
        theta0 = self._xyt[i, 2]
        dx, dy = _arc_displacement(theta0, k, sigma)
        out = np.stack([self._xyt[i, 0] + dx, self._xyt[i, 1] + dy, theta0 + k * sigma,
                        self._s[i] + sigma, np.where(inside, v, 0.0),
                        np.where(inside, k * v, 0.0)], axis=-1)
        return out

    def pose(self, t_ns: np.ndarray | int) -> np.ndarray:
        """Pose (..., 3) = x_m, y_m, theta_rad (wrapped to [-pi, pi)) at ``t_ns``."""
        xyt = self._state(t_ns)[..., :3]
        xyt[..., 2] = _wrap(xyt[..., 2])
        return xyt

    def velocity(self, t_ns: np.ndarray | int) -> tuple[np.ndarray, np.ndarray]:
        """(speed_mps, yaw_rate_radps) at ``t_ns``: exactly the time derivative of :meth:`pose`
        (zero outside ``[start_ns, end_ns]``)."""
        st = self._state(t_ns)
        return st[..., 4], st[..., 5]

    def distance(self, t_ns: np.ndarray | int) -> np.ndarray:
        """Arc length travelled since ``start_ns`` (metres)."""
        return self._state(t_ns)[..., 3]

    def truncated(self, duration_ns: int | None = None,
                  length_m: float | None = None) -> Trajectory:
        """The first ``duration_ns`` and/or first ``length_m`` of this trajectory (the
        shorter wins). The vehicle does not brake: the trajectory just ends there."""
        end = self.end_ns
        if duration_ns is not None:
            end = min(end, self.start_ns + int(duration_ns))
        if length_m is not None and length_m < self.length_m:
            k = int(np.searchsorted(self._s, length_m))
            lo_t = self.start_ns + int(self._t[max(k - 1, 0)] * 1e9)
            hi_t = min(self.start_ns + int(math.ceil(self._t[k] * 1e9)) + 1, self.end_ns)
            while hi_t - lo_t > 1:  # bisection in integer ns on the monotone s(t)
                mid = (lo_t + hi_t) // 2
                if self.distance(mid) < length_m:
                    lo_t = mid
                else:
                    hi_t = mid
            end = min(end, hi_t)
        return Trajectory(self.start_ns, max(end, self.start_ns), self._t, self._s,
                          self._xyt, self._v, self._k)

    def sample(self, period_ns: int = 10_000_000) -> tuple[np.ndarray, np.ndarray]:
        """(t_ns, xyt) every ``period_ns`` from ``start_ns`` to ``end_ns`` (plots, truth)."""
        t = np.append(np.arange(self.start_ns, self.end_ns, period_ns, dtype=np.int64), self.end_ns)
        return t, self.pose(t)
