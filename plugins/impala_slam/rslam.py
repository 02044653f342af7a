"""R-SLAM, the dense radar SLAM of seed 1 §4.1: map matching (eq. 5) then map update (eq. 6).

:class:`RSlamCore` is the algorithm on plain values (used by the component, the tests and
the benchmark); :class:`RSlam` is the dataflow component.

The map frame is the odometry frame of the first panoramic (its 0° is the vehicle's
initial heading, as in the seed). Each new panoramic's pose is predicted from the
previous estimate and the odometry increment between the two grids' poses; without
odometry (``Grid.pose`` is ``None``, e.g. the Oxford scans) a constant-velocity model
extrapolates the last two estimates.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from impala_flow.component import Component, Input, Output, Param, Periodic
from impala_flow.msgs import Grid, Pose2D

from .matching import MatchParams, match_to_map
from .se2 import between, compose
from .tilemap import TileMap, alpha_weight, warp_grid_to_map

__all__ = ["RSlamConfig", "RSlamCore", "RSlam"]

Pose = tuple[float, float, float]


@dataclass
class RSlamConfig:
    match: MatchParams = field(default_factory=MatchParams)
    map_cell_m: float = 0.0  # 0: the first panoramic's cell
    tile_m: float = 64.0
    aperture_deg: float = 4.0  # antenna 3 dB aperture (IMPALA: 4 degrees)
    resolution_m: float = 0.75  # range resolution c / (2 dF)
    range_min_m: float = 3.0
    range_max_m: float = 100.0
    fallback_std_m: float = 0.5  # std added to the prediction when matching fails


class RSlamCore:
    """State of one R-SLAM run: the tiled map and the last estimates."""

    def __init__(self, config: RSlamConfig | None = None) -> None:
        self.cfg = config or RSlamConfig()
        self.map: TileMap | None = None
        self.poses: list[tuple[int, Pose]] = []  # (t_ns, estimate)
        self._last_odom: Pose | None = None
        self.failures = 0
        self.match_s = 0.0
        self.update_s = 0.0

    # --- prediction ------------------------------------------------------------------
    def predict(self, t_ns: int, odom: Pose | None) -> Pose:
        t_prev, prev = self.poses[-1]
        if odom is not None and self._last_odom is not None:
            return compose(prev, between(self._last_odom, odom))
        if len(self.poses) < 2:
            return prev
        t_pp, pp = self.poses[-2]
        d = between(pp, prev)
        w = (t_ns - t_prev) / max(1, t_prev - t_pp)  # constant velocity
        return compose(prev, (w * d[0], w * d[1], w * d[2]))

    def velocity(self) -> tuple[float, float]:
        """(forward speed m/s, yaw rate rad/s) between the last two estimates (0 before)."""
        if len(self.poses) < 2:
            return 0.0, 0.0
        (t0, a), (t1, b) = self.poses[-2], self.poses[-1]
        d = between(a, b)
        dt = (t1 - t0) * 1e-9
        return math.hypot(d[0], d[1]) * math.copysign(1.0, d[0]) / dt, d[2] / dt

    def alpha(self, distance_m: np.ndarray) -> np.ndarray:
        """alpha(d) of eq. (6) with this run's antenna and range limits."""
        c = self.cfg
        return alpha_weight(distance_m, math.radians(c.aperture_deg), c.resolution_m, c.range_min_m, c.range_max_m)

    # --- one turn ----------------------------------------------------------------------
    def step(self, t_ns: int, grid: Grid, odom: Pose | None = None) -> tuple[Pose, np.ndarray, bool]:
        """Locate ``grid`` in the map and merge it; return (pose, 3x3 covariance, matched)."""
        if odom is None and grid.pose is not None:
            odom = (grid.pose.x_m, grid.pose.y_m, grid.pose.theta_rad)
        if self.map is None:
            self.map = TileMap(self.cfg.map_cell_m or grid.cell_m, self.cfg.tile_m)
            pose, cov, ok = (odom or (0.0, 0.0, 0.0)), np.zeros((3, 3)), True
        else:
            pred = self.predict(t_ns, odom)
            t0 = time.perf_counter()
            m = match_to_map(self.map, grid, pred, self.cfg.match, self.alpha)
            self.match_s += time.perf_counter() - t0
            ok = m.valid
            if ok:
                pose, cov = (m.x_m, m.y_m, m.theta_rad), m.cov_xyt
            else:
                self.failures += 1
                pose, cov = pred, np.diag([self.cfg.fallback_std_m ** 2] * 2 + [math.radians(1.0) ** 2])
        t0 = time.perf_counter()
        self.update_map(grid, pose)
        self.update_s += time.perf_counter() - t0
        self.poses.append((t_ns, pose))
        self._last_odom = odom
        return pose, cov, ok

    def update_map(self, grid: Grid, pose: Pose) -> None:
        """Merge the panoramic at ``pose`` into the map: M = 1/N sum alpha(d_i) A_i (eq. 6)."""
        tm = self.map
        assert tm is not None
        half_x = 0.5 * grid.data.shape[1] * grid.cell_m
        half_y = 0.5 * grid.data.shape[0] * grid.cell_m
        reach = min(self.cfg.range_max_m, math.hypot(half_x, half_y))
        ix0, iy0 = tm.index_of(pose[0] - reach, pose[1] - reach)
        n = int(math.ceil(2.0 * reach / tm.cell_m)) + 2
        amp = warp_grid_to_map(grid, pose, ix0, iy0, n, n, tm.cell_m)
        xs = (ix0 + np.arange(n, dtype=np.float32)) * tm.cell_m - pose[0]
        ys = (iy0 + np.arange(n, dtype=np.float32)) * tm.cell_m - pose[1]
        d = np.hypot(xs[None, :], ys[:, None])
        alpha = self.alpha(d)
        covered = np.isfinite(amp) & (alpha > 0)
        tm.add(ix0, iy0, np.where(covered, alpha * np.nan_to_num(amp), 0.0), covered)


class RSlam(Component):
    """Dense radar SLAM (R-SLAM, seed 1 §4.1): each panoramic is located in the global map by
    3-D correlation (eq. 5), then merged into it (eq. 6). Outputs a pose with covariance per
    turn (frame ``map``) and the whole map every ``map_period_s``."""

    image = Input(Grid, doc="motion-corrected panoramic, vehicle frame, pose = odometry at t_ref")
    pose = Output(Pose2D, doc="vehicle pose in the map with cov_xyt (m^2, rad^2)")
    map = Output(Grid, doc="the global radar map (eq. 6)")
    map_timer = Periodic("map_period_s")

    map_period_s = Param(float, default=10.0, gt=0, doc="period of the map output (s)")
    search_m = Param(float, default=2.0, gt=0, doc="translation search half-width around the prediction")
    rot_span_deg = Param(float, default=2.0, gt=0, doc="rotations tried: predicted heading +- span")
    rot_step_deg = Param(float, default=0.5, gt=0, doc="step between rotations")
    match_cell_m = Param(float, default=0.4, gt=0, doc="cell of the coarse correlation")
    match_range_m = Param(float, default=60.0, gt=0, doc="radius of the panoramic used for matching")
    contrast_m = Param(float, default=3.0, gt=0, doc="local-mean window removed before correlating")
    min_score = Param(float, default=0.05, ge=0, le=1, doc="normalised correlation below which matching fails")
    map_cell_m = Param(float, default=0.0, ge=0, doc="map cell (0: the panoramic's)")
    tile_m = Param(float, default=64.0, gt=0, doc="side of the map tiles")
    aperture_deg = Param(float, default=4.0, gt=0, doc="antenna aperture for alpha(d) of eq. (6)")
    resolution_m = Param(float, default=0.75, gt=0, doc="range resolution for alpha(d) of eq. (6)")
    range_min_m = Param(float, default=3.0, ge=0, doc="blind range: not merged")
    range_max_m = Param(float, default=100.0, gt=0, doc="radar range: not merged beyond")

    def start(self) -> None:
        mp = MatchParams(self.search_m, self.rot_span_deg, self.rot_step_deg, self.match_cell_m,
                         self.match_range_m, self.contrast_m, self.min_score)
        self.core = RSlamCore(RSlamConfig(mp, self.map_cell_m, self.tile_m, self.aperture_deg,
                                          self.resolution_m, self.range_min_m, self.range_max_m))
        self.turns = 0

    def process(self, t: int) -> None:
        if self.trigger == "map_timer":
            if self.core.map is not None and not self.core.map.empty:
                self.map.emit(t, self.core.map.to_grid())
            return
        sample = self.image.take_sample()
        (x, y, th), cov, _ = self.core.step(sample.timestamp, sample.data)
        self.turns += 1
        self.pose.emit(sample.timestamp, Pose2D(x, y, th, cov, "map"))

    def flush(self, t: int) -> None:
        """The mission is over: emit the final map (whatever the map period)."""
        if self.core.map is not None and not self.core.map.empty:
            self.map.emit(t, self.core.map.to_grid())

    def summary(self) -> dict:
        core = getattr(self, "core", None)
        if core is None or not self.turns:
            return {}
        tm = core.map
        return {
            "turns": self.turns,
            "match_failures": core.failures,
            "match_ms_per_turn": round(1e3 * core.match_s / self.turns, 2),
            "update_ms_per_turn": round(1e3 * core.update_s / self.turns, 2),
            "map_tiles": tm.n_tiles if tm else 0,
            "map_mb": round((tm.nbytes if tm else 0) / 2 ** 20, 1),
        }
