"""R-SLAM, the dense radar SLAM of seed 1 §4.1: map matching (eq. 5) then map update (eq. 6).

:class:`RSlamCore` is the algorithm on plain values (used by the component, the tests and
the benchmark); :class:`RSlam` is the dataflow component.

The map frame is the odometry frame of the first panoramic (its 0° is the vehicle's
initial heading, as in the seed). Each new panoramic's pose is predicted from the
previous estimate and the odometry increment between the two grids' poses; without
odometry (``Grid.pose`` is ``None``, e.g. the Oxford scans) a constant-velocity model
extrapolates the last two estimates.

What the seed leaves free, and the values chosen (measured on the simulated Beynes mission,
662 turns, 708 m; ``bench/rslam.py``):

- **A, the amplitude of eq. (5)-(6)**: ``intensity = "db"``, A = 10 log10(P / floor). The
  panoramic's power spans 50 dB and more; correlated as linear power the match rests on a
  few bright near speckle cells and hardly sees the rotation (0.35 deg heading error per
  match against a perfect map, 1.8 m ATE and 3 % drift over 200 m). In dB: 0.05 deg and
  1.5 cm per match, 0.07 m ATE and 0.03 % drift over the whole mission. Images already in
  dB (Navtech PNGs) use ``"linear"``.
- **The normaliser of eq. (6)**: ``map_update = "weighted"`` (default), M = sum alpha A /
  sum alpha, the running weighted mean (alpha a confidence): a cell reads the echo's level
  whatever the distance it was seen from, and a place seen once (at the edge of the range,
  behind an obstacle) counts as much as one seen every turn. ``"paper"`` is eq. (6) as the
  seed writes it, M = 1/N sum alpha A with N the total number of images merged: a cell seen
  in many images outweighs a transient (a parked car that left, a place glimpsed once), but
  the map's level grows where the vehicle lingered and carries the footprint of alpha
  along the trajectory. ``"count"`` divides by the number of images that covered each
  cell. The weighted mean is the default because the correlation (eq. 5) compares levels:
  on Beynes it gave the lower error. The template is A itself, not alpha A
  (``MatchParams.weight_template``).
- **alpha(d)**: 1 / (1 + d aperture / resolution) within [range_min, range_max]
  (:func:`~impala_slam.tilemap.alpha_weight`; IMPALA: 4 deg, 0.75 m, 3-100 m).
- **Search**: +-2 m around the odometry prediction, rotations +-1 deg by 0.25 deg (the gyro
  predicts the heading to about 0.1 deg per turn), matching disk 60 m, coarse level 0.4 m.
  The span's rotations are climbed from the last turn's innovation (match minus prediction:
  on Beynes the gyro's bias, 0.1-0.2 deg a turn), not all correlated: 4 coarse and 3.2 fine
  correlations a Beynes turn instead of 9 and 4, with the same poses unless the peaks have two
  summits within the span (then the climb may find the higher one: :func:`match_to_map`).
- **Missing turns** (real logs: RADIATE's radar log has gaps of up to 1.6 s): without
  odometry the constant-velocity prediction continues the last increment along its arc
  (:func:`~impala_slam.se2.repeat`), and a prediction spanning more than 1.5 ordinary
  intervals first searches that many times the rotation span (:func:`match_to_map`'s
  ``widen``). Measured on RADIATE's Edinburgh head with five gaps of 1.6-1.75 s cut into
  it while driving (a 25 deg bend among them): ATE 3.25 m -> 1.07 m of 332 m (1.06 m without
  the gaps); the straight-line extrapolation put the pose 4 m off the road in the bend.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from impala_flow.msgs import Grid

from ..se2 import between, compose, repeat
from ..tilemap import TileMap, alpha_weight, warp_grid_to_map
from .matching import MatchParams, match_to_map
from .sharing import resolved, shared_map

__all__ = ["RSlamConfig", "RSlamCore"]

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
    intensity: str = "db"  # "db": A = 10 log10(P / floor), >= 0; "linear": A = the grid's value
    db_floor: float = 0.0  # floor of the dB scale (the grid's unit); 0: db_floor_quantile of each image
    db_floor_quantile: float = 0.001  # quantile of the observed cells taken as 0 dB when db_floor is 0
    map_update: str = "weighted"  # eq. (6) normaliser: "weighted" sum alpha, "paper" N images, "count" per cell
    map_max_mb: float = 0.0  # bound of the map's tiles (MiB): the farthest from the vehicle dropped; 0: none
    threads: int = 1  # threads sharing a turn's rotations and warps (results bit-identical whatever the number)


class RSlamCore:
    """State of one R-SLAM run: the tiled map and the last estimates."""

    def __init__(self, config: RSlamConfig | None = None) -> None:
        self.cfg = config or RSlamConfig()
        self.map: TileMap | None = None
        self.poses: list[tuple[int, Pose]] = []  # (t_ns, estimate)
        self._last_odom: Pose | None = None
        self.last_prediction: Pose | None = None  # the motion model's pose of the last step
        self.failures = 0
        self.match_s = 0.0
        self.update_s = 0.0
        # thread CPU seconds per stage: amplitude, prepare, coarse, fine (matching), update
        self.split: dict[str, float] = {}
        self._alpha_key: tuple | None = None
        self._rot_hint = 0.0  # the last match's heading minus its prediction: where the next turn's search starts
        self._alpha_img = np.zeros((0, 0), np.float32)
        # threads - 1 helpers: the calling thread always takes its share (close() ends them)
        self._workers = max(0, int(self.cfg.threads) - 1)
        self._pool = ThreadPoolExecutor(self._workers, "rslam") if self._workers else None

    def close(self) -> None:
        """End the helper threads (``threads`` > 1); the core then runs on the calling thread."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool, self._workers = None, 0

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
        return compose(prev, repeat(d, w))  # constant velocity: the last increment's arc continued

    def gap_ratio(self, t_ns: int) -> float:
        """How many ordinary intervals (the median of the last ones) separate ``t_ns`` from
        the last estimate; 1 unless it is over 1.5 (turns missing from the log: the
        matching then searches that many times wider, see :func:`match_to_map`)."""
        if len(self.poses) < 3:
            return 1.0
        ts = np.array([t for t, _ in self.poses[-11:]], np.int64)
        usual = float(np.median(np.diff(ts)))
        r = (t_ns - int(ts[-1])) / usual if usual > 0 else 1.0
        return r if r > 1.5 else 1.0

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

    def amplitude(self, grid: Grid) -> Grid:
        """The panoramic on the scale R-SLAM correlates and maps (``intensity``).

        ``"db"``: A = 10 log10(P / floor), 0 where not observed. The simulated (and any
        physical) power image spans 50 dB and more (R^-4, metal sheds against grass): on
        that linear scale the correlation is carried by a few near, bright speckle cells and
        hardly depends on the rotation (Beynes: heading error 0.35 deg per turn with a
        perfect map). In dB every range and every kind of echo counts: 0.05 deg, 1.5 cm.
        ``floor`` is ``db_floor`` or the ``db_floor_quantile`` of the observed cells: the
        noise level. Beynes-like scenes are clutter everywhere, the noise is their 0.1 %
        quantile (the far grass a few dB above it is signal: a median floor doubles the
        heading error); a few points over a noise floor (``impala_slam.synthetic``) need 0.5.
        """
        if self.cfg.intensity == "linear":
            return grid
        p = np.asarray(grid.data, np.float32)
        floor = self.cfg.db_floor
        if floor <= 0.0:
            sub = p[::4, ::4]
            sub = sub[sub > 0]
            if sub.size == 0:
                return grid
            k = int(self.cfg.db_floor_quantile * (sub.size - 1))
            floor = float(np.partition(sub, k)[k])
        # in the log domain (a subnormal floor would overflow p / floor in float32)
        a = np.maximum(p, np.float32(floor))
        cv2.log(a, dst=a)  # in place: one image allocated, not two
        from ._jit import db_tail  # numba: loaded in start(), not with the plugin

        # (a - ln floor) * 10 / ln 10 where p > 0, 0 elsewhere, in one compiled pass (the same float32 bits
        # as numpy's subtract, multiply and masked copy, four passes through the image)
        db_tail(a, p, np.float32(math.log(floor)), np.float32(10.0 / math.log(10.0)))
        return Grid(a, grid.cell_m, grid.origin_x_m, grid.origin_y_m, grid.frame, grid.pose)

    # --- one turn ----------------------------------------------------------------------
    def step(self, t_ns: int, grid: Grid, odom: Pose | None = None) -> tuple[Pose, np.ndarray, bool]:
        """Locate ``grid`` in the map and merge it; return (pose, 3x3 covariance, matched)."""
        if odom is None and grid.pose is not None:
            odom = (grid.pose.x_m, grid.pose.y_m, grid.pose.theta_rad)
        if self.map is None:
            grid = self._timed("amplitude", self.amplitude, grid)
            self.map = TileMap(self.cfg.map_cell_m or grid.cell_m, self.cfg.tile_m,
                               total_normaliser=self.cfg.map_update == "paper")
            pose = self.last_prediction = odom or (0.0, 0.0, 0.0)
            return self._merge(t_ns, grid, odom, pose, np.zeros((3, 3)), True)
        # the dB image on a helper thread, when there is one, while the map windows are read
        amp: Grid | Future = (self._pool.submit(self._timed, "amplitude", self.amplitude, grid) if self._pool
                              else self._timed("amplitude", self.amplitude, grid))
        pred = self.last_prediction = self.predict(t_ns, odom)
        t0 = time.perf_counter()
        m = match_to_map(self.map, amp, pred, self.cfg.match, self.alpha, self.gap_ratio(t_ns), self.split,
                         self._pool, self._workers, self._rot_hint)
        self.match_s += time.perf_counter() - t0
        ok = m.valid and bool(np.all(np.isfinite([m.x_m, m.y_m, m.theta_rad])) and np.all(np.isfinite(m.cov_xyt)))
        self._rot_hint = math.remainder(m.theta_rad - pred[2], math.tau) if ok else 0.0
        if ok:
            pose, cov = (m.x_m, m.y_m, m.theta_rad), m.cov_xyt
        else:
            self.failures += 1
            pose, cov = pred, np.diag([self.cfg.fallback_std_m ** 2] * 2 + [math.radians(1.0) ** 2])
        return self._merge(t_ns, resolved(amp), odom, pose, cov, ok)

    def _timed(self, stage: str, fn: Callable, *args: Any) -> Any:
        """fn(*args), its thread CPU added to ``split[stage]``, whichever thread runs it (one
        stage is never added to by two threads at once)."""
        c0 = time.thread_time()
        out = fn(*args)
        self.split[stage] = self.split.get(stage, 0.0) + time.thread_time() - c0
        return out

    def _merge(self, t_ns: int, grid: Grid, odom: Pose | None, pose: Pose, cov: np.ndarray,
               ok: bool) -> tuple[Pose, np.ndarray, bool]:
        """Merge the turn's dB image into the map at ``pose`` and record it."""
        t0 = time.perf_counter()
        self._timed("update", self.update_map, grid, pose)
        if self.cfg.map_max_mb > 0:
            self.map.bound(int(self.cfg.map_max_mb * 2 ** 20), pose[0], pose[1])
        self.update_s += time.perf_counter() - t0
        self.poses.append((t_ns, pose))
        self._last_odom = odom
        return pose, cov, ok

    def _alpha_image(self, grid: Grid) -> np.ndarray:
        """(rows, cols) float32 alpha(d) over the panoramic's own cells (d from the radar at the
        vehicle origin), kept while the grid's geometry is."""
        key = (grid.data.shape, grid.cell_m, grid.origin_x_m, grid.origin_y_m)
        if self._alpha_key != key:
            xs = grid.origin_x_m + grid.cell_m * np.arange(grid.data.shape[1], dtype=np.float64)
            ys = grid.origin_y_m + grid.cell_m * np.arange(grid.data.shape[0], dtype=np.float64)
            self._alpha_img = np.empty(grid.data.shape, np.float32)
            for i in range(0, len(ys), 32):  # by bands of rows: the float64 temporaries stay in cache
                self._alpha_img[i:i + 32] = self.alpha(np.hypot(xs[None, :], ys[i:i + 32, None]))
            self._alpha_key = key
        return self._alpha_img

    def update_map(self, grid: Grid, pose: Pose) -> None:
        """Merge the panoramic at ``pose`` into the map (eq. 6).

        ``map_update = "weighted"``: M = sum alpha(d_i) A_i / sum alpha(d_i), the running
        weighted mean; ``"paper"``: M = 1/N sum alpha(d_i) A_i with N the number of images
        merged (eq. 6 as written); ``"count"``: N the number of images that covered the cell.
        With N, a cell seen only from afar reads lower than the same echo seen from near
        (alpha < 1), so the map holds the trajectory's footprint as well as the scene."""
        tm = self.map
        assert tm is not None
        half_x = 0.5 * grid.data.shape[1] * grid.cell_m
        half_y = 0.5 * grid.data.shape[0] * grid.cell_m
        reach = min(self.cfg.range_max_m, math.hypot(half_x, half_y))
        ix0, iy0 = tm.index_of(pose[0] - reach, pose[1] - reach)
        n = int(math.ceil(2.0 * reach / tm.cell_m)) + 2
        # amplitude and alpha(d) (radial around the radar) resampled alike, each by a single-channel
        # warp: OpenCV 5 interpolates one channel with exact float coordinates (2.5e-5 dB RMS from a
        # float64 bilinear on Beynes) where its 2-channel warp, twice as slow, rounds them to 1/32 of
        # a cell (0.012 dB RMS, up to 0.87 dB). A cell is covered where the amplitude is defined (NaN
        # outside the panoramic) and alpha > 0: TileMap.add merges only those
        alpha_img = self._alpha_image(grid)
        if self._pool is not None:  # the two warps side by side (each the same call on its own data)
            job = self._pool.submit(self._timed, "update", warp_grid_to_map, grid, pose, ix0, iy0, n, n,
                                    tm.cell_m, 0.0, alpha_img)
            amp = warp_grid_to_map(grid, pose, ix0, iy0, n, n, tm.cell_m)
            alpha = job.result()
        else:
            amp = warp_grid_to_map(grid, pose, ix0, iy0, n, n, tm.cell_m)
            alpha = warp_grid_to_map(grid, pose, ix0, iy0, n, n, tm.cell_m, 0.0, data=alpha_img)
        from ._jit import merge_tile  # numba: loaded at the first update, not with the plugin

        weighted = self.cfg.map_update == "weighted"
        tm.add_with(ix0, iy0, n, n, lambda win, ws, cnt: merge_tile(amp[win], alpha[win], ws, cnt, weighted),
                    self._run)
        tm.images += 1

    def _run(self, fn: Callable, items: list) -> list:
        """[fn(x) for x in items], shared with the helper threads (each item its own data)."""
        out, cpu = shared_map(self._pool, self._workers, fn, items)
        self.split["update"] = self.split.get("update", 0.0) + cpu
        return out
