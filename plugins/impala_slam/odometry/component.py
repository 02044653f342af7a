"""``slam.DistortionOdometry``: the component (ports, parameters, sample handling). The algorithm, and
what it follows, is described in :mod:`impala_slam.odometry.core`.
"""

from __future__ import annotations

import importlib
import math
import time

import numpy as np

from impala_flow import Component, Input, Output, Param, Periodic
from impala_flow.msgs import Grid, Pose2D, Scalar, Twist2D
from impala_msgs import RadarBeam

from ..tilemap import TileMap
from .core import DistortionConfig, DistortionCore, TurnResult
from .distortion import (
    EchoParams,
)

__all__ = ["DistortionOdometry"]


class DistortionOdometry(Component):
    """Radar-only odometry from the distortion of the scans (seed 1 §4.2, Figs. 13-16): no
    odometer, no gyro. Beams in (any beams per turn, either rotation sense, with or without
    Doppler ramps); per turn out: ``twist`` (V, w with covariance, Kalman-filtered), ``pose``
    (integrated, frame ``odom``), ``degraded`` (1 when the turn gave no measurement: the
    covariance grows) and every ``map_period_s`` the map of the echoes' power placed by the
    odometry's own poses (Fig. 16). Outputs are stamped at the first beam of the newer of the
    two turns compared, on the turn clock (earlier than the turn's stamp when that came late).
    Never a NaN: before its first measurement it emits nothing. A turn short of beams (beams
    lost or invalid, the recording's ends) is used as it is when it holds ``min_turn_fraction``
    of them (counted as ``partial_turns``), else dropped (``dropped_turns``).
    """

    beams = Input(RadarBeam, doc="radar beams, each stamped at its own time")
    twist = Output(Twist2D, doc="speed and yaw rate at the turn boundary, with covariance (v, w)")
    pose = Output(Pose2D, doc="integrated pose (frame odom), with covariance")
    degraded = Output(Scalar, doc="1 when the turn gave no velocity measurement (prediction only), else 0")
    map = Output(Grid, doc="echo power placed by the odometry's own poses (dB above the beam median)")
    map_timer = Periodic("map_period_s")

    threshold_db = Param(float, default=12.0, gt=0, doc="echoes: local maxima this far above their beam's median")
    max_echoes = Param(int, default=250, gt=0, doc="echoes kept per turn and ramp (the strongest)")
    window_bins = Param(int, default=5, ge=3, doc="local-maximum window in range bins")
    range_min_m = Param(float, default=3.0, ge=0, doc="echoes nearer are ignored")
    range_max_m = Param(float, default=80.0, gt=0, doc="echoes farther are ignored")
    doppler = Param(bool, default=True, doc="remove the range-Doppler coupling with the estimated speed")
    max_speed_mps = Param(float, default=25.0, gt=0, doc="search range of the speed (forward)")
    max_reverse_mps = Param(float, default=3.0, ge=0, doc="search range of the speed (backward)")
    max_yaw_rate_dps = Param(float, default=30.0, gt=0, doc="search range of the yaw rate")
    gate_m = Param(float, default=1.0, gt=0, doc="first association gate (from the search's start)")
    sigma_range_m = Param(float, default=0.0, ge=0, doc="echo range std (0: half the range resolution)")
    sigma_azimuth_deg = Param(float, default=0.3, gt=0, doc="echo azimuth std")
    min_pairs = Param(int, default=12, ge=3, doc="fewer associated echoes: no measurement (degraded)")
    accel_std_mps2 = Param(float, default=1.0, gt=0, doc="filter: change of acceleration per second")
    yaw_accel_std_dps2 = Param(float, default=3.0, gt=0, doc="filter: change of yaw rate per second")
    map_cell_m = Param(float, default=0.5, ge=0, doc="map cell (0: no map)")
    map_range_m = Param(float, default=60.0, gt=0, doc="beams placed in the map up to this range")
    map_period_s = Param(float, default=30.0, gt=0, doc="period of the map output (s)")
    frame = Param(str, default="odom", doc="frame of the poses and of the map")
    min_turn_fraction = Param(float, default=0.5, ge=0, le=1,
                              doc="a turn with fewer beams (of beams_per_turn) is dropped (counted); one with "
                                  "more but not all is used as it is (counted as partial)")

    def start(self) -> None:
        cfg = DistortionConfig(
            EchoParams(self.threshold_db, self.max_echoes, 0, self.window_bins, self.range_min_m, self.range_max_m),
            self.doppler, self.max_speed_mps, self.max_reverse_mps, math.radians(self.max_yaw_rate_dps),
            self.gate_m, self.sigma_range_m, math.radians(self.sigma_azimuth_deg), self.min_pairs,
            self.accel_std_mps2, math.radians(self.yaw_accel_std_dps2))
        self.core = DistortionCore(cfg)
        # the filter's library (filterpy loads scipy.stats: 0.5-0.8 s) loaded now, not in a live radar's first turn
        importlib.import_module("filterpy.kalman")
        self._beams: list[tuple[int, RadarBeam]] = []
        self._turn: int | None = None
        self._t0: int | None = None
        self._pose_cov = np.zeros((3, 3))
        self._map = TileMap(self.map_cell_m) if self.map_cell_m > 0 else None
        self._last_turn: tuple | None = None  # (t_s, azimuths, dB above beam medians, config) of the previous turn
        self._last_result: TurnResult | None = None
        self.partial_turns = 0  # turns short of beams, used
        self.dropped_turns = 0  # turns with fewer than min_turn_fraction of their beams, not used
        self.map_s = 0.0
        # the compiled loops (numba, from its cache) loaded now: the first turns do not wait for them
        from ._jit import warm_up

        warm_up()

    def process(self, t: int) -> None:
        if self.trigger == "map_timer":
            if self._map is not None and not self._map.empty:
                self.map.emit(t, self._map.to_grid(self.frame))
            return
        s = self.beams.take_sample()
        beam: RadarBeam = s.data
        if self._turn is not None and beam.turn != self._turn:
            self._close_turn()
        self._turn = beam.turn
        self._beams.append((s.timestamp, beam))

    def flush(self, t: int) -> None:
        """The mission is over: the last turn if complete, then the final map."""
        self._close_turn()
        if self._map is not None and not self._map.empty:
            self.map.emit(t, self._map.to_grid(self.frame))

    def _close_turn(self) -> None:
        beams, self._beams = self._beams, []
        if not beams:
            return
        config = beams[0][1].config
        if len(beams) < config.beams_per_turn:  # cut by the recording's start or end, or beams lost
            if len(beams) < max(2.0, self.min_turn_fraction * config.beams_per_turn):
                self.dropped_turns += 1  # too few beams to compare with the previous turn
                return
            self.partial_turns += 1  # its beams carry their own times and azimuths: used as they are
        if self._t0 is None:
            self._t0 = beams[0][0]
        t_ns = np.array([b[0] for b in beams], np.int64)
        t_s = (t_ns - self._t0) * 1e-9
        az = np.array([b[1].azimuth_rad for b in beams])
        up = np.stack([b[1].up for b in beams])
        down = np.stack([b[1].down for b in beams]) if config.doppler and beams[0][1].down.size else None
        r = self.core.step(t_s, az, up, down, config)
        if r is not None and math.isfinite(r.v_mps):
            # stamped on the turn clock (earlier than the turn's stamp when that came late)
            self._emit(int(t_ns.min()) - int(round(r.clock_offset_s * 1e9)), r)
            if self._map is not None and self._last_turn is not None:
                self._add_to_map(r)
        self._last_turn = (self.core.beam_times_s, az, self.core.up_rel_db, config)
        if r is not None and math.isfinite(r.v_mps):
            self._last_result = r

    def _emit(self, t_ns: int, r: TurnResult) -> None:
        self.twist.emit(t_ns, Twist2D(r.v_mps, r.w_radps, r.cov))
        prev = self._last_result
        if prev is not None:  # first order: the mean velocity's covariance over the step
            dt = r.t_s - prev.t_s
            th = prev.pose[2]
            j = np.array([[math.cos(th) * dt, 0.0], [math.sin(th) * dt, 0.0], [0.0, dt]])
            self._pose_cov = self._pose_cov + j @ (0.5 * (r.cov + prev.cov)) @ j.T
        x, y, th = r.pose
        self.pose.emit(t_ns, Pose2D(x, y, th, self._pose_cov.copy(), self.frame))
        self.degraded.emit(t_ns, Scalar(1.0 if r.degraded else 0.0))

    def _add_to_map(self, r: TurnResult) -> None:
        """The previous turn's beams placed along the arc between its pose and this one."""
        t0 = time.thread_time()
        prev = self._last_result
        t_s, az, rel_db, config = self._last_turn
        if prev is None:
            return
        vm, wm = 0.5 * (prev.v_mps + r.v_mps), 0.5 * (prev.w_radps + r.w_radps)
        poses = self.core.beam_poses(t_s, prev.t_s, prev.pose, vm, wm)
        from ._jit import map_cells

        k = np.arange(rel_db.shape[1])
        rng = np.asarray(config.range_of_bin_m(k), float)
        cols = np.flatnonzero((rng >= self.range_min_m) & (rng <= self.map_range_m))
        a = poses[:, 2:3] + az[:, None]
        # dB above the beam medians (the odometry's echo extraction computed them), at least 0, summed per cell
        ix0, iy0, total, count = map_cells(np.ascontiguousarray(poses[:, 0]), np.ascontiguousarray(poses[:, 1]),
                                           np.cos(a).ravel(), np.sin(a).ravel(), rng[cols], rel_db, cols,
                                           self._map.cell_m)
        tm = self._map
        s, n = total.astype(np.float32), count.astype(np.float32)
        tm.add(ix0, iy0, s, n)
        tm.images += 1
        self.map_s += time.thread_time() - t0

    def summary(self) -> dict:
        core = getattr(self, "core", None)
        if core is None:
            return {}
        if not core.turns:  # no turn reached the estimator: say why (turns cut short)
            return ({"turns": 0, "partial_turns": self.partial_turns, "dropped_turns": self.dropped_turns}
                    if self.partial_turns or self.dropped_turns else {})
        return {
            "turns": core.turns,
            "degraded_turns": core.degraded,
            "searches": core.searches,
            "wide_searches": core.wide_searches,
            "filter_resets": core.resets,
            "late_stamps": core.late_stamps,
            "missing_turns": core.missing_turns,
            "partial_turns": self.partial_turns,
            "dropped_turns": self.dropped_turns,
            "odo_ms_per_turn": round(1e3 * core.seconds / core.turns, 2),
            "first_registration_ms": round(1e3 * (core.first_s or 0.0), 1),
            "map_ms_per_turn": round(1e3 * self.map_s / core.turns, 2),
            **{f"{k}_ms_per_turn": round(1e3 * v / core.turns, 2) for k, v in core.split_s.items()},
        }
