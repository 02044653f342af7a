"""``tracking.Tracker``: the component (ports, parameters, sample handling). The algorithm, and
what it follows, is described in :mod:`impala_tracking.tracker.core`.
"""

from __future__ import annotations

import importlib

import numpy as np

from impala_flow import Component, Input, Output, Param
from impala_msgs import ObjectStates, TrackExistence

from ..types import MoverDetections
from .core import (
    Track,
    cv_noise,
    cv_transition,
    existence_update,
    line_of_sight,
    measurement_cov,
    measurement_matrix,
    pair_distances,
)

__all__ = ["Tracker"]


class Tracker(Component):
    """Per turn of :class:`MoverDetections`: predict, associate (Mahalanobis on position and
    Doppler, gated, ``linear_sum_assignment``), update one constant-velocity Kalman filter per
    track, update existence probabilities, confirm, delete, start tracks (see the module doc).
    Emits the confirmed tracks as ObjectStates (positions and velocities predicted to the turn
    time, 4x4 covariances) and every live track's existence probability."""

    detections = Input(MoverDetections, doc="moving objects of one turn (tracking.MoverDetector)")
    tracks = Output(ObjectStates, doc="confirmed tracks at the turn time")
    existence = Output(TrackExistence, doc="every live track and its existence probability")

    accel_sigma_mps2 = Param(float, default=0.5, gt=0, doc="white-acceleration std of the CV model")
    gate_prob = Param(float, default=0.999, gt=0, lt=1, doc="chi-square gate (3 dof) probability")
    pd = Param(float, default=0.7, gt=0, lt=1, doc="detection probability of a visible mover")
    pf = Param(float, default=0.02, gt=0, lt=1, doc="probability of a false detection in a track's gate")
    p_birth = Param(float, default=0.2, gt=0, lt=1, doc="existence probability of a new track")
    p_survive = Param(float, default=0.98, gt=0, le=1, doc="existence kept from one turn to the next")
    p_confirm = Param(float, default=0.75, gt=0, lt=1, doc="confirmation threshold")
    p_delete = Param(float, default=0.02, gt=0, lt=1, doc="deletion threshold")
    blind_speed_mps = Param(float, default=1.5, ge=0, doc="detector's minimum ground radial speed (Pd' model)")
    max_range_m = Param(float, default=100.0, gt=0,
                        doc="radar range: beyond it a track is not expected to be detected, and is deleted")
    init_cross_sigma_mps = Param(float, default=10.0, gt=0,
                                 doc="prior std of a new track's speed across the line of sight")
    birth_exclusion_m = Param(float, default=5.0, ge=0,
                              doc="no new track within this distance of a confirmed one (its own echoes, ghosts)")
    max_pos_sigma_m = Param(float, default=15.0, gt=0, doc="tracks whose position std exceeds it are deleted")

    def start(self) -> None:
        self.live: list[Track] = []
        self.next_id = 1
        self.turn = 0
        # here, not at import: scipy.stats, scipy.optimize and filterpy cost 0.85 s to import (scipy.optimize
        # 0.3 s more: every command's start paid it), paid by graphs that track only, and before the first
        # sample (a live run's first turn is not late)
        from scipy.stats import chi2

        importlib.import_module("scipy.optimize")
        importlib.import_module("scipy.special")

        importlib.import_module("filterpy.kalman")
        self.gate_d2 = float(chi2.ppf(self.gate_prob, 3))
        self._radar_xy = np.zeros(2)
        self.n_born = 0
        self.n_confirmed = 0
        self.lifetimes: list[tuple[int, int, bool]] = []  # (id, turns lived, ever confirmed)

    def process(self, t: int) -> None:
        det: MoverDetections = self.detections.take()
        self.turn += 1
        self._radar_xy = np.asarray(det.sensor_xy_m, float)
        n_t, n_d = len(self.live), len(det.t_ns)
        assigned_det = np.full(n_t, -1)
        in_gate = np.zeros(n_d, bool)
        if n_t and n_d:
            x = np.array([tr.kf.x[:, 0] for tr in self.live])
            p = np.array([tr.kf.P for tr in self.live])
            tt = np.array([tr.t_ns for tr in self.live], np.int64)
            d2, logdet = pair_distances(x, p, tt, det, self.accel_sigma_mps2)
            ok = d2 <= self.gate_d2
            in_gate = ok.any(axis=0)
            cost = np.where(ok, d2 + logdet, 1e9)
            from scipy.optimize import linear_sum_assignment  # loaded in start()

            rows, cols = linear_sum_assignment(cost)
            for r, c in zip(rows, cols, strict=True):
                if ok[r, c]:
                    assigned_det[r] = c
        u = line_of_sight(det) if n_d else np.zeros((0, 2))
        rmat = measurement_cov(det) if n_d else np.zeros((0, 3, 3))
        for i, tr in enumerate(self.live):
            j = assigned_det[i]
            pd_eff = self.pd * self._visible(tr, t)
            tr.p *= self.p_survive
            if j >= 0:
                self._predict(tr, int(det.t_ns[j]))
                z = np.array([[det.xy_m[j, 0]], [det.xy_m[j, 1]], [det.radial_speed_mps[j]]])  # a column: filterpy
                tr.kf.update(z, R=rmat[j], H=measurement_matrix(u[j]))
                tr.p = existence_update(tr.p, True, max(pd_eff, 1e-3), self.pf)
                tr.hits += 1
                tr.misses = 0
            else:
                tr.p = existence_update(tr.p, False, pd_eff, self.pf)
                tr.misses += 1
            if not tr.confirmed and tr.p >= self.p_confirm:
                tr.confirmed = True
                self.n_confirmed += 1
        survivors = []
        for tr in self.live:
            pos_sigma = float(np.sqrt(max(tr.kf.P[0, 0], tr.kf.P[1, 1])))
            now_xy = tr.kf.x[:2, 0] + tr.kf.x[2:, 0] * (t - tr.t_ns) * 1e-9
            gone = float(np.hypot(*(now_xy - self._radar_xy))) > self.max_range_m  # left the field of view
            if tr.p < self.p_delete or pos_sigma > self.max_pos_sigma_m or gone:
                self.lifetimes.append((tr.id, self.turn - tr.born_turn, tr.confirmed))
            else:
                survivors.append(tr)
        self.live = survivors
        used = set(int(j) for j in assigned_det if j >= 0)
        near = self._near_confirmed(det.xy_m, det.t_ns) if n_d else np.zeros(0, bool)
        for j in range(n_d):
            if j not in used and not in_gate[j] and not near[j]:
                self.live.append(self._new_track(det, j, u[j], rmat[j]))
        self._emit(t, det.frame)

    def _near_confirmed(self, xy: np.ndarray, t_ns: np.ndarray) -> np.ndarray:
        """Detections within ``birth_exclusion_m`` of a confirmed track predicted to their time
        (its other echoes, ghost pairs of its peaks) start no track."""
        conf = [tr for tr in self.live if tr.confirmed]
        if not conf:
            return np.zeros(len(xy), bool)
        x = np.array([tr.kf.x[:, 0] for tr in conf])
        dt = (t_ns[None, :] - np.array([tr.t_ns for tr in conf], np.int64)[:, None]) * 1e-9
        px, py = x[:, 0:1] + x[:, 2:3] * dt, x[:, 1:2] + x[:, 3:4] * dt
        d = np.hypot(xy[None, :, 0] - px, xy[None, :, 1] - py)
        return d.min(axis=0) <= self.birth_exclusion_m

    def _visible(self, tr: Track, t_ns: int) -> float:
        """Probability that the detector can see the track now: in range, and its predicted
        ground radial speed beyond the blind speed (Gaussian on the predicted v_r)."""
        x, p = tr.kf.x[:, 0], tr.kf.P
        rel = x[:2] - self._radar_xy
        rng = float(np.hypot(*rel))
        if rng > self.max_range_m:
            return 0.0
        u = rel / max(rng, 1e-9)
        m = float(u @ x[2:])
        s = float(np.sqrt(max(u @ p[2:, 2:] @ u, 1e-6)))
        b = self.blind_speed_mps
        from scipy.special import ndtr  # loaded in start()

        return float(1.0 - (ndtr((b - m) / s) - ndtr((-b - m) / s)))

    def _predict(self, tr: Track, t_ns: int) -> None:
        dt = (t_ns - tr.t_ns) * 1e-9
        tr.kf.predict(F=cv_transition(dt), Q=cv_noise(dt, self.accel_sigma_mps2))
        tr.t_ns = t_ns

    def _new_track(self, det: MoverDetections, j: int, u: np.ndarray, r: np.ndarray) -> Track:
        from filterpy.kalman import KalmanFilter  # loaded in start()

        kf = KalmanFilter(dim_x=4, dim_z=3)
        kf.x = np.array([[det.xy_m[j, 0]], [det.xy_m[j, 1]], [det.radial_speed_mps[j] * u[0]],
                         [det.radial_speed_mps[j] * u[1]]])
        w = np.array([-u[1], u[0]])
        kf.P = np.zeros((4, 4))
        kf.P[:2, :2] = r[:2, :2]
        kf.P[2:, 2:] = r[2, 2] * np.outer(u, u) + self.init_cross_sigma_mps**2 * np.outer(w, w)
        tr = Track(self.next_id, kf, int(det.t_ns[j]), self.p_birth, self.turn)
        self.next_id += 1
        self.n_born += 1
        return tr

    def _emit(self, t: int, frame: str) -> None:
        xs, ps = [], []
        for tr in self.live:
            dt = (t - tr.t_ns) * 1e-9
            f = cv_transition(dt)
            xs.append(f @ tr.kf.x[:, 0])
            ps.append(f @ tr.kf.P @ f.T + cv_noise(dt, self.accel_sigma_mps2))
        x = np.array(xs).reshape(-1, 4)
        pcov = np.array(ps).reshape(-1, 4, 4)
        ids = np.array([tr.id for tr in self.live], np.int64)
        conf = np.array([tr.confirmed for tr in self.live], bool)
        prob = np.array([tr.p for tr in self.live], float)
        self.existence.emit(t, TrackExistence(ids, x[:, :2].copy(), prob, conf, frame))
        self.tracks.emit(t, ObjectStates(ids[conf], x[conf, :2].copy(), x[conf, 2:].copy(), pcov[conf], frame))

    def flush(self, t: int) -> None:
        for tr in self.live:
            self.lifetimes.append((tr.id, self.turn - tr.born_turn + 1, tr.confirmed))

    def summary(self) -> dict:
        return {"turns": self.turn, "tracks_born": self.n_born, "tracks_confirmed": self.n_confirmed,
                "live_at_end": len(self.live)}
