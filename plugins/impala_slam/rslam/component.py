"""``slam.RSlam``: the component (ports, parameters, sample handling). The algorithm, and
what it follows, is described in :mod:`impala_slam.rslam.core`.
"""

from __future__ import annotations

import numpy as np

from impala_flow import Component, Input, Output, Param, Periodic
from impala_flow.msgs import Grid, Pose2D, Twist2D

from ..se2 import between, compose
from .core import Pose, RSlamConfig, RSlamCore
from .matching import MatchParams

__all__ = ["RSlam"]


class RSlam(Component):
    """Dense radar SLAM (R-SLAM, seed 1 §4.1): each panoramic is located in the global map by
    3-D correlation (eq. 5), then merged into it (eq. 6). Outputs a pose with covariance per
    turn (frame ``map``), the velocity between the last two poses (``twist``: connect it
    back to the panoramic builder with ``[delay]`` to motion-correct a radar without
    odometry), the motion model's own trajectory (``prediction``: the predicted increments,
    odometry or constant velocity, chained without matching; the baseline R-SLAM must beat),
    and the whole map every ``map_period_s``.

    ``threads`` (default 2) share a turn's work: the dB image, the rotations of each level, the
    fine panoramic and templates, the map update's warps and tiles run on a helper thread
    beside the calling one (made in ``start()``, ended in ``stop()``). Poses, covariances and
    map are bit-identical whatever the number; the wall time per turn falls, not the CPU.

    A NaN or infinite pose is never emitted: a match that fails (peak on the window's
    border, too weak, empty image, non-finite result) keeps the prediction and is counted
    in ``match_failures``; images with no observed cell are counted in ``empty_images``."""

    image = Input(Grid, doc="motion-corrected panoramic, vehicle frame, pose = odometry at t_ref (or None)")
    pose = Output(Pose2D, doc="vehicle pose in the map with cov_xyt (m^2, rad^2)")
    twist = Output(Twist2D, doc="forward speed and yaw rate between the last two poses, with covariance")
    prediction = Output(Pose2D, doc="the motion model's increments chained (frame odom): the baseline")
    map = Output(Grid, doc="the global radar map M of eq. (6), in the unit of A (dB with intensity db)")
    map_timer = Periodic("map_period_s")

    map_period_s = Param(float, default=10.0, gt=0, doc="period of the map output (s)")
    search_m = Param(float, default=2.0, gt=0, doc="translation search half-width around the prediction")
    rot_span_deg = Param(float, default=1.0, gt=0, doc="rotations tried: predicted heading +- span")
    rot_step_deg = Param(float, default=0.25, gt=0, doc="step between rotations")
    match_cell_m = Param(float, default=0.4, gt=0, doc="cell of the coarse correlation")
    match_range_m = Param(float, default=60.0, gt=0, doc="radius of the panoramic used for matching")
    contrast_m = Param(float, default=3.0, gt=0, doc="local-mean window removed before correlating")
    min_score = Param(float, default=0.05, ge=0, le=1, doc="normalised correlation below which matching fails")
    smooth_m = Param(float, default=0.0, ge=0, doc="Gaussian sigma before correlating (at least 0.6 cell)")
    intensity = Param(str, default="db", choices=("db", "linear"), doc="scale of A in eq. (5)-(6): dB or as given")
    db_floor = Param(float, default=0.0, ge=0, doc="0 dB level of the dB scale (0: db_floor_quantile of the image)")
    db_floor_quantile = Param(float, default=0.001, ge=0, lt=1,
                              doc="quantile of the observed cells taken as 0 dB (the noise level)")
    map_update = Param(str, default="weighted", choices=("weighted", "paper", "count"),
                       doc="eq. (6) normaliser: sum alpha (weighted mean), N images (the paper), N per cell")
    map_cell_m = Param(float, default=0.0, ge=0, doc="map cell (0: the panoramic's)")
    tile_m = Param(float, default=64.0, gt=0, doc="side of the map tiles")
    map_max_mb = Param(float, default=48.0, ge=0,
                       doc="bound of the map's memory (MiB): the tiles farthest from the vehicle are dropped (0: none)")
    aperture_deg = Param(float, default=4.0, gt=0, doc="antenna aperture for alpha(d) of eq. (6)")
    resolution_m = Param(float, default=0.75, gt=0, doc="range resolution for alpha(d) of eq. (6)")
    range_min_m = Param(float, default=3.0, ge=0, doc="blind range: not merged")
    range_max_m = Param(float, default=100.0, gt=0, doc="radar range: not merged beyond")
    threads = Param(int, default=2, ge=1, le=4,
                    doc="threads sharing a turn's work (poses and map bit-identical whatever the number)")

    def start(self) -> None:
        from . import _jit  # noqa: F401  the compiled loops loaded (or compiled once) now, not at the first turns

        mp = MatchParams(self.search_m, self.rot_span_deg, self.rot_step_deg, self.match_cell_m,
                         self.match_range_m, self.contrast_m, self.min_score, self.smooth_m)
        self.core = RSlamCore(RSlamConfig(mp, self.map_cell_m, self.tile_m, self.aperture_deg,
                                          self.resolution_m, self.range_min_m, self.range_max_m,
                                          intensity=self.intensity, db_floor=self.db_floor,
                                          db_floor_quantile=self.db_floor_quantile, map_update=self.map_update,
                                          map_max_mb=self.map_max_mb, threads=self.threads))
        self.turns = 0
        self.empty_images = 0
        self._predicted: Pose | None = None  # the motion model's chained trajectory
        self._cov_prev = np.zeros((3, 3))

    def process(self, t: int) -> None:
        if self.trigger == "map_timer":
            if self.core.map is not None and not self.core.map.empty:
                self.map.emit(t, self.core.map.to_grid())
            return
        sample = self.image.take_sample()
        grid: Grid = sample.data
        if not np.any(np.asarray(grid.data) > 0):
            self.empty_images += 1
        core = self.core
        prev = core.poses[-1][1] if core.poses else None
        (x, y, th), cov, _ = core.step(sample.timestamp, grid)
        self.turns += 1
        self.pose.emit(sample.timestamp, Pose2D(x, y, th, cov, "map"))
        step = (0.0, 0.0, 0.0) if prev is None else between(prev, core.last_prediction)
        self._predicted = (x, y, th) if self._predicted is None else compose(self._predicted, step)
        px, py, pth = self._predicted
        self.prediction.emit(sample.timestamp, Pose2D(px, py, pth, frame="odom"))
        if len(core.poses) >= 2:
            (t0, _), (t1, _) = core.poses[-2], core.poses[-1]
            dt = (t1 - t0) * 1e-9
            v, w = core.velocity()
            # first-order: the two poses' covariances (independent) through the difference / dt
            c = (self._cov_prev + cov) / (dt * dt)
            tw_cov = np.array([[c[0, 0], c[0, 2]], [c[2, 0], c[2, 2]]])
            self.twist.emit(sample.timestamp, Twist2D(v, w, tw_cov))
        self._cov_prev = cov

    def stop(self) -> None:
        core = getattr(self, "core", None)
        if core is not None:
            core.close()

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
            "empty_images": self.empty_images,
            "match_ms_per_turn": round(1e3 * core.match_s / self.turns, 2),
            "update_ms_per_turn": round(1e3 * core.update_s / self.turns, 2),
            # thread CPU per stage (profile-derived split of match + update)
            **{f"{k}_cpu_ms_per_turn": round(1e3 * v / self.turns, 2) for k, v in core.split.items()},
            "map_tiles": tm.n_tiles if tm else 0,
            "map_tiles_dropped": tm.dropped_tiles if tm else 0,
            "map_mb": round((tm.nbytes if tm else 0) / 2 ** 20, 1),
        }
