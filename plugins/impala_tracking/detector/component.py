"""``tracking.MoverDetector``: the component (ports, parameters, sample handling). The algorithm, and
what it follows, is described in :mod:`impala_tracking.detector.core`.
"""

from __future__ import annotations

import importlib

import numpy as np

from impala_flow import Component, Input, Output, Param
from impala_flow.msgs import Pose2D
from impala_msgs import RadarDetections, Speed

from ..types import MoverDetections
from .core import ClutterMap, absorb_ghosts, cluster_candidates, ground_radial_speed_mps

__all__ = ["MoverDetector"]


class MoverDetector(Component):
    """Per turn of paired detections: remove the ego-Doppler, keep the detections off the
    static-Doppler curve by more than their uncertainty, cluster them per object, filter
    false ones (amplitude, clutter map, persistence) and emit :class:`MoverDetections` with
    position and radial-speed covariances (see the module doc). Without a ``speed`` sample
    the radar is static (ego speed 0); without ``pose`` the frame is the radar's own."""

    detections = Input(RadarDetections, doc="paired detections of one turn (radar.FuzzyPairer)")
    speed = Input(Speed, policy="sampling", required=False, doc="ego speed (radar.EgoVelocity, odometer)")
    pose = Input(Pose2D, policy="sampling", history=5.0, required=False,
                 doc="radar pose (RTK-GPS, odometry): detections are placed in its frame at their beam time")
    movers = Output(MoverDetections, doc="moving objects of the turn")

    doppler_sigma_mps = Param(float, default=0.25, gt=0, doc="radial-speed measurement std of one pair")
    n_sigma = Param(float, default=3.0, gt=0, doc="candidate: |ground radial speed| > n_sigma x its std")
    min_radial_speed_mps = Param(float, default=1.5, ge=0, doc="candidate: and |ground radial speed| > this")
    radar_height_m = Param(float, default=1.3, ge=0, doc="radar height (ground-echo depression factor)")
    min_score = Param(float, default=0.0, ge=0, le=1, doc="pairs scoring less are ignored")
    min_amplitude = Param(float, default=0.0, ge=0, doc="objects whose peak amplitude is lower are dropped")
    min_beams = Param(int, default=2, ge=1, doc="objects seen in fewer beams are dropped")
    max_beam_gap = Param(int, default=5, ge=1, doc="clustering: beams apart")
    max_range_gap_m = Param(float, default=5.0, gt=0, doc="clustering: range apart")
    max_speed_gap_mps = Param(float, default=1.5, gt=0, doc="clustering: radial speed apart")
    range_sigma_m = Param(float, default=0.5, gt=0, doc="range std of an object (resolution, extent)")
    azimuth_sigma_deg = Param(float, default=1.5, gt=0, doc="azimuth std of an object (beam width / sqrt 12 ...)")
    extent_sigma_m = Param(float, default=1.0, ge=0, doc="isotropic std added for the object's extent (car: ~1 m)")
    ghost_radius_m = Param(float, default=3.0, ge=0,
                           doc="small clusters this near a big one are its ghost pairs: position kept, "
                               "Doppler not (0: off)")
    ghost_max_beams = Param(int, default=2, ge=1, doc="largest ghost cluster (detections)")
    clutter_cell_m = Param(float, default=3.0, gt=0, doc="clutter map cell")
    clutter_tau_turns = Param(float, default=30.0, gt=1, doc="clutter map memory (turns)")
    clutter_rate = Param(float, default=0.2, gt=0, doc="clutter: cells with more candidates per turn than this")
    persistence_turns = Param(int, default=0, ge=0,
                              doc="keep an object only if one was within reach in the last N turns (0: off)")
    max_target_speed_mps = Param(float, default=25.0, gt=0, doc="persistence reach per second")

    def start(self) -> None:
        importlib.import_module("scipy.sparse.csgraph")  # before the first turn (core imports it where it is used)
        self.clutter = ClutterMap(self.clutter_cell_m, self.clutter_tau_turns, self.clutter_rate)
        self._recent: list[tuple[int, np.ndarray]] = []
        self.turns = 0
        self.n_candidates = 0
        self.n_objects = 0
        self.rejected = {"amplitude": 0, "clutter": 0, "persistence": 0, "beams": 0}

    def process(self, t: int) -> None:
        d: RadarDetections = self.detections.take()
        self.turns += 1
        sp = self.speed.get()
        speed = float(sp.speed_mps) if sp is not None else 0.0
        speed_std = float(sp.std_mps) if sp is not None and np.isfinite(sp.std_mps) else 0.0
        v_raised, v_ground = ground_radial_speed_mps(d.radial_speed_mps, d.azimuth_rad, d.range_m, speed,
                                                     self.radar_height_m)
        sigma = np.hypot(self.doppler_sigma_mps, np.cos(d.azimuth_rad) * speed_std)
        gate = np.maximum(self.n_sigma * sigma, self.min_radial_speed_mps)
        off = np.abs(v_raised) > gate
        if speed != 0.0:  # a ground echo must be off the curve under its own factor too
            off &= ~(np.abs(v_ground) <= gate)
        cand = np.nonzero(off & np.isfinite(v_raised) & (np.nan_to_num(d.score, nan=1.0) >= self.min_score))[0]
        self.n_candidates += len(cand)
        n_beams = int(d.beam.max(initial=0)) + 1  # beams of the turn (for the wrap through azimuth 0)
        labels = cluster_candidates(d.beam[cand], d.range_m[cand], v_raised[cand], n_beams, self.max_beam_gap,
                                    self.max_range_gap_m, self.max_speed_gap_mps)
        out = self._objects(t, d, cand, labels, v_raised, sigma)
        self.movers.emit(t, out)

    def _objects(self, t: int, d: RadarDetections, cand: np.ndarray, labels: np.ndarray, v_mps: np.ndarray,
                 sigma: np.ndarray) -> MoverDetections:
        n = int(labels.max()) + 1 if len(labels) else 0
        amp = d.amplitude[cand].astype(float)
        w = np.maximum(amp, 1e-30)
        az = d.azimuth_rad[cand]
        own = np.ones(len(labels), bool)
        if n and self.ghost_radius_m > 0:  # small clusters beside a big one: its ghost pairs
            target = absorb_ghosts(labels, d.range_m[cand], az, w, self.ghost_radius_m, self.ghost_max_beams)
            own = target[labels] == labels
            _, labels = np.unique(target[labels], return_inverse=True)
            n = int(labels.max()) + 1
        wsum = np.bincount(labels, w, n)
        mean = lambda x: np.bincount(labels, w * x, n) / wsum  # noqa: E731
        az_obj = np.arctan2(mean(np.sin(az)), mean(np.cos(az)))
        r_obj = mean(d.range_m[cand])
        w_own = np.bincount(labels, w * own, n)  # Doppler from the object's own pairs, not its ghosts
        v_obj = np.bincount(labels, w * own * v_mps[cand], n) / w_own
        var_obj = np.bincount(labels, w * own * sigma[cand] ** 2, n) / w_own
        # time: amplitude-weighted, in ns relative to the turn's first beam to keep precision
        t0 = int(d.t_ns.min()) if len(d.t_ns) else 0
        t_obj = (t0 + np.round(mean((d.t_ns[cand] - t0).astype(float)))).astype(np.int64)
        amp_max = np.zeros(n)
        np.maximum.at(amp_max, labels, amp)
        n_b = np.bincount(labels, minlength=n)
        xy, cov, radar_xy, frame = self._place(t_obj, r_obj, az_obj)
        keep = np.ones(n, bool)
        low = amp_max < self.min_amplitude
        few = n_b < self.min_beams
        clut = self.clutter.is_clutter(xy) if n else np.zeros(0, bool)
        pers = self._not_persistent(t_obj, xy) if n else np.zeros(0, bool)
        self.clutter.update(xy[~low & ~few])
        for key, m in (("amplitude", low), ("beams", few & ~low), ("clutter", clut & ~low & ~few),
                       ("persistence", pers & ~clut & ~low & ~few)):
            self.rejected[key] += int(m.sum())
        keep = ~(low | few | clut | pers)
        self.n_objects += int(keep.sum())
        sensor = self._place(np.array([t], np.int64), np.zeros(1), np.zeros(1))[2][0]
        return MoverDetections(d.turn, t_obj[keep], xy[keep], cov[keep], v_obj[keep], var_obj[keep],
                               radar_xy[keep], r_obj[keep], amp_max[keep], n_b[keep].astype(np.int64), sensor, frame)

    def _place(self, t_ns: np.ndarray, range_m: np.ndarray, az_rad: np.ndarray):
        """Positions and covariances in the pose frame at each object's time."""
        n = len(t_ns)
        radar = np.zeros((n, 3))
        frame = "radar"
        if self.pose.get() is not None:
            frame = self.pose.get().frame
            for i, t in enumerate(t_ns):
                p = self.pose.at(int(t), clamp=True)
                radar[i] = p.x_m, p.y_m, p.theta_rad
        bearing = radar[:, 2] + az_rad
        c, s = np.cos(bearing), np.sin(bearing)
        xy = radar[:, :2] + range_m[:, None] * np.column_stack([c, s])
        sr2 = self.range_sigma_m**2
        sa2 = (range_m * np.radians(self.azimuth_sigma_deg)) ** 2
        u, v = np.column_stack([c, s]), np.column_stack([-s, c])
        cov = (sr2 * u[:, :, None] * u[:, None, :] + sa2[:, None, None] * v[:, :, None] * v[:, None, :]
               + self.extent_sigma_m**2 * np.eye(2)[None])
        return xy, cov, radar[:, :2].copy(), frame

    def _not_persistent(self, t_ns: np.ndarray, xy: np.ndarray) -> np.ndarray:
        if self.persistence_turns == 0:
            return np.zeros(len(xy), bool)
        ok = np.zeros(len(xy), bool)
        for t_prev, xy_prev in self._recent:
            if len(xy_prev) == 0:
                continue
            reach = self.max_target_speed_mps * np.abs(t_ns - t_prev) * 1e-9 + 3.0
            dist = np.hypot(*(xy[:, None, :] - xy_prev[None, :, :]).transpose(2, 0, 1)).min(axis=1)
            ok |= dist <= reach
        self._recent.append((int(np.median(t_ns)), xy.copy()))
        self._recent = self._recent[-self.persistence_turns:]
        return ~ok

    def summary(self) -> dict:
        return {"turns": self.turns, "candidates": self.n_candidates, "objects": self.n_objects,
                **{f"rejected_{k}": v for k, v in self.rejected.items() if v}}
