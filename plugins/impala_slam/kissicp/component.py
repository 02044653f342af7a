"""``slam.KissIcp``: the component (ports, parameters, sample handling). The algorithm, and
what it follows, is described in :mod:`impala_slam.kissicp.core`.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from impala_flow import Component, Input, Output, Param
from impala_flow.msgs import Pose2D, Twist2D
from impala_msgs import RadarDetections

from .. import se2
from ..se2 import between
from .core import planar_pose, pose_matrix, scaled_twist

__all__ = ["KissIcp"]


MISSING = "slam.KissIcp needs the kiss-icp package: pip install 'impala-flow[peers]'"


class KissIcp(Component):
    """kiss-icp odometry on radar point detections (see :mod:`impala_slam.kissicp.component`).

    Parameters map onto kiss-icp's configuration: ``max_range_m``/``min_range_m`` (data),
    ``voxel_size_m``/``max_points_per_voxel`` (mapping), ``initial_threshold_m``/
    ``min_motion_m`` (adaptive threshold), ``max_iterations``/``convergence``/``threads``
    (registration), ``deskew``.
    """

    detections = Input(RadarDetections, maxsize=256, doc="one turn of point detections, each with its beam's time")
    pose = Output(Pose2D, doc="registered pose (frame odom) at each turn's last point")
    twist = Output(Twist2D, doc="mean velocity since the previous turn (body frame)")

    max_range_m = Param(float, default=100.0, gt=0, doc="points farther are dropped; the local map's radius")
    min_range_m = Param(float, default=0.0, ge=0, doc="points nearer are dropped")
    voxel_size_m = Param(float, default=1.0, gt=0, doc="voxel of the local map (the frame: 0.5 and 1.5 times it)")
    max_points_per_voxel = Param(int, default=20, ge=1, doc="points kept per voxel of the map")
    initial_threshold_m = Param(float, default=2.0, gt=0, doc="correspondence threshold before any motion is seen")
    min_motion_m = Param(float, default=0.1, ge=0, doc="motions below this do not update the adaptive threshold")
    deskew = Param(bool, default=True, doc="move every point to the pose at the turn's last point (constant velocity)")
    max_iterations = Param(int, default=500, ge=1, doc="ICP iterations at most")
    convergence = Param(float, default=1e-4, gt=0, doc="ICP stops when the update is below this")
    threads = Param(int, default=1, ge=0, doc="kiss-icp's threads (0: all cores; 1 keeps runs bit-identical)")
    min_points = Param(int, default=20, ge=1, doc="a turn with fewer points is not registered")
    map_min_motion_m = Param(float, default=0.0, ge=0,
                             doc="a turn updates the local map only once the pose moved this far (or turned "
                             "map_min_motion_m / 10 rad) since the last update; 0: every turn, as kiss-icp")

    def start(self) -> None:
        try:
            from kiss_icp.config import KISSConfig
            from kiss_icp.config.config import (
                AdaptiveThresholdConfig,
                DataConfig,
                MappingConfig,
                RegistrationConfig,
            )
            from kiss_icp.kiss_icp import KissICP
            from kiss_icp.preprocess import Preprocessor
        except ImportError as e:
            raise RuntimeError(MISSING) from e
        config = KISSConfig(
            data=DataConfig(max_range=self.max_range_m, min_range=self.min_range_m, deskew=False),
            mapping=MappingConfig(voxel_size=self.voxel_size_m, max_points_per_voxel=self.max_points_per_voxel),
            registration=RegistrationConfig(max_num_iterations=self.max_iterations,
                                            convergence_criterion=self.convergence, max_num_threads=self.threads),
            adaptive_threshold=AdaptiveThresholdConfig(initial_threshold=self.initial_threshold_m,
                                                       min_motion_th=self.min_motion_m))
        self._icp: Any = KissICP(config)
        self._map_pose: tuple[float, float, float] | None = None  # pose of the last map update
        self._boot: list[tuple[np.ndarray, np.ndarray, float, np.ndarray]] = []  # the first turns, as seen
        self.map_updates = 0
        if self.map_min_motion_m > 0:
            update = self._icp.local_map.update

            def gated_update(points: np.ndarray, pose: np.ndarray) -> None:
                p = planar_pose(pose)
                if self._map_pose is not None:
                    dx, dy, dth = between(self._map_pose, p)
                    if math.hypot(dx, dy) < self.map_min_motion_m and abs(dth) < 0.1 * self.map_min_motion_m:
                        return
                self._map_pose = p
                self.map_updates += 1
                update(points, pose)

            self._icp.local_map.update = gated_update
        self._deskewer = (Preprocessor(self.max_range_m, self.min_range_m, True, self.threads)
                          if self.deskew else None)
        self._t_prev: int | None = None  # stamp (last point) of the previous registered turn
        self._dt_delta: float | None = None  # seconds spanned by the icp's last_delta
        self.turns = 0
        self.skipped_turns = 0
        self.points = 0
        self.seconds = 0.0

    def process(self, t: int) -> None:
        det: RadarDetections = self.detections.take()
        n = len(det.range_m)
        if n < self.min_points:
            self.skipped_turns += 1
            return
        t0 = time.perf_counter()
        t_ns = np.asarray(det.t_ns, np.int64)
        t_first, t_ref = int(t_ns.min()), int(t_ns.max())
        span = (t_ref - t_first) * 1e-9
        icp = self._icp
        first = self._t_prev is None
        dt = span if first else (t_ref - self._t_prev) * 1e-9
        r = np.asarray(det.range_m, np.float64)
        a = np.asarray(det.azimuth_rad, np.float64)
        points = np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros(n)])
        if not first and dt > 0 and self._dt_delta:
            twist = se2.log(planar_pose(icp.last_delta))
            icp.last_delta = scaled_twist(twist, dt / self._dt_delta)  # the prediction: from the last turn to this one
            if self._deskewer is not None and span > 0:
                points = self._deskewer.preprocess(points, (t_ns - t_first) * 1e-9,
                                                   scaled_twist(twist, span / self._dt_delta))
        before = planar_pose(icp.last_pose)
        raw = points if self.turns < 2 and self._deskewer is not None else None
        icp.register_frame(points, np.zeros(n))  # kiss-icp's own deskew is off: done above
        x, y, theta = planar_pose(icp.last_pose)
        # keep kiss-icp's state in the plane: z, roll and pitch are unobservable from planar points
        icp.last_pose = pose_matrix(x, y, theta)
        step = between(before, (x, y, theta))
        icp.last_delta = pose_matrix(*step)
        if raw is not None:
            self._boot.append((raw, (t_ns - t_first) * 1e-9, span, icp.last_pose.copy()))
            if len(self._boot) == 2 and dt > 0:
                self._rebuild_map(se2.log(step), dt)
        self._dt_delta = dt
        self._t_prev = t_ref
        self.turns += 1
        self.points += n
        self.seconds += time.perf_counter() - t0
        self.pose.emit(t_ref, Pose2D(x, y, theta, frame="odom"))
        if not first and dt > 0:
            vx, _, w = se2.log(step)
            self.twist.emit(t_ref, Twist2D(vx / dt, w / dt))

    def _rebuild_map(self, twist: tuple[float, float, float], dt: float) -> None:
        """The first two turns entered the map as seen (no motion known to deskew them): once the
        second is registered, the map is made again from both deskewed with the motion between
        them, so that the next (deskewed) turns meet an undistorted map."""
        icp = self._icp
        icp.local_map.clear()
        self._map_pose = None
        for raw, t_rel, span, pose in self._boot:
            frame = self._deskewer.preprocess(raw, t_rel, scaled_twist(twist, span / dt)) if span > 0 else raw
            icp.local_map.update(icp.voxelize(frame)[1], pose)
        self._boot = []

    def summary(self) -> dict:
        if not getattr(self, "turns", 0):  # nothing registered: say why (turns with too few points)
            return {"turns": 0, "skipped_turns": self.skipped_turns} if getattr(self, "skipped_turns", 0) else {}
        return {"turns": self.turns, "skipped_turns": self.skipped_turns, "map_updates": self.map_updates or self.turns,
                "points_per_turn": round(self.points / self.turns, 1),
                "ms_per_turn": round(1e3 * self.seconds / self.turns, 2)}
