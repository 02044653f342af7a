"""A synthetic radar world for tests and benchmarks: point scatterers seen as panoramic grids.

Independent of the radar simulator: scatterers of known positions are splatted into a
vehicle-frame grid at a known pose, blurred to the radar's resolution, with a fresh
speckle-like noise every turn, so the true pose of every panoramic is known exactly.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import cv2
import numpy as np

from impala_flow.msgs import Grid, Pose2D
from impala_msgs import Speed, YawRate

__all__ = ["SyntheticWorld", "grid_shape", "beynes_like_path", "synthetic_mission"]


def grid_shape(radius_m: float, cell_m: float) -> tuple[int, float]:
    """(cells per side, origin) of a square grid centred on the radar."""
    half = int(math.ceil(radius_m / cell_m))
    return 2 * half + 1, -half * cell_m


@dataclass
class SyntheticWorld:
    xy_m: np.ndarray  # (N, 2) scatterer positions
    amplitude: np.ndarray  # (N,)

    @classmethod
    def random(cls, rng: np.random.Generator, x_range_m: tuple[float, float], y_range_m: tuple[float, float],
               density_per_m2: float = 0.03, n_clusters: int = 0) -> SyntheticWorld:
        """Uniform clutter (bushes, grass tufts) plus ``n_clusters`` bright sheds (walls)."""
        area = (x_range_m[1] - x_range_m[0]) * (y_range_m[1] - y_range_m[0])
        n = rng.poisson(density_per_m2 * area)
        xy = np.column_stack([rng.uniform(*x_range_m, n), rng.uniform(*y_range_m, n)])
        amp = rng.lognormal(0.0, 0.8, n)
        parts, amps = [xy], [amp]
        for _ in range(n_clusters):  # a shed: a rectangle outline of strong echoes
            c = np.array([rng.uniform(*x_range_m), rng.uniform(*y_range_m)])
            w, h = rng.uniform(6, 20, 2)
            s = np.linspace(0, 1, 25)
            edges = np.concatenate([np.column_stack([s * w, 0 * s]), np.column_stack([s * w, 0 * s + h]),
                                    np.column_stack([0 * s, s * h]), np.column_stack([0 * s + w, s * h])])
            parts.append(c + edges)
            amps.append(np.full(len(edges), 3.0))
        return cls(np.concatenate(parts), np.concatenate(amps))

    def render(self, pose_xyt: tuple[float, float, float], rng: np.random.Generator, cell_m: float = 0.2,
               radius_m: float = 60.0, blur_m: float = 0.35, noise: float = 0.05,
               odom: tuple[float, float, float] | None = None, range_min_m: float = 3.0) -> Grid:
        """Panoramic seen from ``pose_xyt`` (vehicle frame, radar at the centre cell);
        ``odom`` is written as the grid's pose (frame ``odom``)."""
        n, origin = grid_shape(radius_m, cell_m)
        x, y, th = pose_xyt
        c, s = math.cos(th), math.sin(th)
        d = self.xy_m - (x, y)
        u = c * d[:, 0] + s * d[:, 1]
        v = -s * d[:, 0] + c * d[:, 1]
        r = np.hypot(u, v)
        keep = (r < radius_m) & (r > range_min_m)
        col = (u[keep] - origin) / cell_m
        row = (v[keep] - origin) / cell_m
        amp = self.amplitude[keep] * rng.gamma(4.0, 0.25, keep.sum())  # per-turn fluctuation
        img = np.zeros((n, n), np.float64)
        c0, r0 = np.floor(col).astype(int), np.floor(row).astype(int)
        fc, fr = col - c0, row - r0
        for dr, dc, w in ((0, 0, (1 - fr) * (1 - fc)), (0, 1, (1 - fr) * fc), (1, 0, fr * (1 - fc)), (1, 1, fr * fc)):
            rr, cc = r0 + dr, c0 + dc
            ok = (rr >= 0) & (rr < n) & (cc >= 0) & (cc < n)
            np.add.at(img, (rr[ok], cc[ok]), amp[ok] * w[ok])
        img = cv2.GaussianBlur(img.astype(np.float32), (0, 0), blur_m / cell_m)
        img += noise * rng.exponential(1.0, img.shape).astype(np.float32)  # speckle floor
        rr = np.hypot(*np.meshgrid(np.arange(n) * cell_m + origin, np.arange(n) * cell_m + origin))
        img[(rr > radius_m) | (rr < range_min_m)] = 0.0
        pose = Pose2D(*odom, frame="odom") if odom is not None else None
        return Grid(img, cell_m, origin, origin, "vehicle", pose)


def beynes_like_path(n_turns: int, speed_mps: float = 1.15, turn_period_s: float = 1.0,
                     seed: int = 0, dt_s: float = 0.05) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A smooth wandering path at constant speed (Beynes: 1.15 m/s, one turn a second):
    (t_s, x_m, y_m, theta_rad) sampled every ``dt_s``, plus its yaw rate (rad/s) as 4th."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, n_turns * turn_period_s + 2 * dt_s, dt_s)
    periods = rng.uniform(60.0, 200.0, 3)
    amps = rng.uniform(0.01, 0.03, 3)
    phases = rng.uniform(0, 2 * np.pi, 3)
    w = sum(a * np.sin(2 * np.pi * t / p + f) for a, p, f in zip(amps, periods, phases, strict=True))
    th = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * dt_s)])
    thm = np.concatenate([[0.0], 0.5 * (th[1:] + th[:-1])])
    x = np.cumsum(speed_mps * dt_s * np.cos(thm)) - speed_mps * dt_s
    y = np.cumsum(speed_mps * dt_s * np.sin(thm))
    return t, np.column_stack([x, y, th]), np.full_like(t, speed_mps), w


def synthetic_mission(n_turns: int, seed: int = 0, cell_m: float = 0.2, radius_m: float = 60.0,
                      speed_scale_err: float = 0.02, gyro_bias_radps: float = 0.002,
                      sensor_rate_hz: float = 20.0) -> Iterator[tuple[int, str, object]]:
    """A Beynes-like mission as time-ordered ``(t_ns, port, msg)``: ``odometer`` (Speed) and
    ``gyro`` (YawRate) with a scale error, a bias and noise, ``image`` (Grid at each turn's
    end, its pose the dead reckoning of those sensors) and ``truth`` (Pose2D, 10 Hz)."""
    rng = np.random.default_rng(seed + 1)
    dt = 1.0 / sensor_rate_hz
    t_s, xyt, v, w = beynes_like_path(n_turns, seed=seed, dt_s=dt)
    lo, hi = xyt[:, :2].min(axis=0) - radius_m - 5, xyt[:, :2].max(axis=0) + radius_m + 5
    world = SyntheticWorld.random(rng, (lo[0], hi[0]), (lo[1], hi[1]), 0.03, max(2, n_turns // 60))
    v_meas = v * (1.0 + speed_scale_err) + rng.normal(0, 0.02, len(t_s))
    w_meas = w + gyro_bias_radps + rng.normal(0, 0.002, len(t_s))
    # odometry pose at every sensor time (midpoint rates, exact arcs), as DeadReckoning does
    odo = np.zeros_like(xyt)
    for k in range(1, len(t_s)):
        vm, wm = 0.5 * (v_meas[k] + v_meas[k - 1]), 0.5 * (w_meas[k] + w_meas[k - 1])
        h = 0.5 * wm * dt
        sinc = math.sin(h) / h if abs(h) > 1e-9 else 1.0
        ds = vm * dt * sinc
        odo[k] = odo[k - 1] + (ds * math.cos(odo[k - 1, 2] + h), ds * math.sin(odo[k - 1, 2] + h), 2 * h)
    t_ns = np.rint(t_s * 1e9).astype(np.int64)
    per_turn = int(round(1.0 / dt))
    for k in range(len(t_s)):  # a generator: one grid in memory at a time
        yield int(t_ns[k]), "odometer", Speed(float(v_meas[k]))
        yield int(t_ns[k]), "gyro", YawRate(float(w_meas[k]))
        if k % 2 == 0:
            yield int(t_ns[k]), "truth", Pose2D(*map(float, xyt[k]), frame="world")
        if k and k % per_turn == 0:
            g = world.render(tuple(xyt[k]), rng, cell_m, radius_m, odom=tuple(map(float, odo[k])))
            yield int(t_ns[k]), "image", g
