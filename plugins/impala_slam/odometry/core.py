"""Radar-only odometry from scan distortion (seed 1 §4.2): beams in, speed, yaw rate, pose out.

Per turn (:class:`DistortionCore`):

0. the turn's time on a turn clock (the radar turns steadily; a log's stamps may come late,
   then catch up): a gap of n turns is n - 1 missing turns or a late stamp, whichever makes
   the echoes coincide at the prediction; beams squeezed between two stamps are spread over
   one rotation;
1. echoes of the turn (:func:`~.distortion.extract_echoes`, both ramps of a Doppler radar);
2. the Kalman filter over (V, a, w) (filterpy; a the longitudinal acceleration, so the
   braking into a roundabout is predicted) predicts the velocities at the boundary between
   the previous turn and this one; on a slow radar (the largest yaw acceleration would turn
   the scene by more than a beam width over a turn: IMPALA's 1 Hz, not Navtech's 4 Hz) the
   pair's motion model has a yaw acceleration too (the rate changes over two turns in a
   roundabout), estimated with (V, w) around the slope of the last turns' rates;
3. the two turns' echoes are made to coincide from that prediction
   (:func:`~.distortion.estimate_velocity`); the result is kept when its coincidence score
   (strongest echoes, range-compensated) reaches ``accept_ratio`` of the last turns'. Else a
   grid search (:func:`~.distortion.search_velocity`) within 3 sigma of the prediction (the
   whole speed and yaw-rate range on the first turn, and when even the best candidate
   scores below ``lost_ratio``: a loss) gives the start of the refinement;
4. the filter is updated with it (a measurement more than ``reset_nis`` away in normalised
   innovation while well supported by coincidences re-initialises the filter: a sudden
   stop); without a measurement it only predicts: the covariance grows and the turn
   counts as ``degraded``;
5. the pose is integrated along the arc of the mean velocities between boundaries.

The velocity estimated from two turns is their mean over the time the same echoes were seen
twice, centred on the boundary: outputs are stamped at the first beam of the newer turn (one
turn of latency, as any two-turn method).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..dead_reckoning.core import arc_step
from .distortion import (
    Echoes,
    EchoParams,
    VelocityEstimate,
    arc_poses,
    doppler_beta_s,
    estimate_velocity,
    extract_echoes,
    search_velocity,
)

if TYPE_CHECKING:
    from filterpy.kalman import KalmanFilter

__all__ = ["DistortionConfig", "DistortionCore", "TurnResult"]


@dataclass
class DistortionConfig:
    echoes: EchoParams = EchoParams()
    doppler: bool = True  # remove the range-Doppler coupling with the estimated speed
    max_speed_mps: float = 25.0
    max_reverse_mps: float = 3.0
    max_yaw_rate_radps: float = math.radians(30.0)
    gate_m: float = 1.0  # first association gate (halved at each iteration)
    sigma_range_m: float = 0.0  # 0: half the range resolution c / (2 dF)
    sigma_azimuth_rad: float = math.radians(0.3)
    min_pairs: int = 12
    accel_std_mps2: float = 1.0  # white jerk of the (V, a) model, per second
    yaw_accel_std_radps2: float = math.radians(3.0)
    reset_nis: float = 25.0
    search_v_step: float = 0.25
    search_w_step: float = math.radians(1.0)
    search_gate_m: float = 0.6
    accept_ratio: float = 0.85  # the prediction's result is kept above this share of the recent coincidences
    lost_ratio: float = 0.6  # best coincidences near the prediction below this share of the recent ones: search all
    yaw_accel: bool = True  # a yaw acceleration in the pair's motion model (where it shows, see _step)
    max_yaw_accel_radps2: float = math.radians(20.0)
    yaw_accel_window_s: float = 0.75
    yaw_accel_prior_std_radps2: float = math.radians(5.0)  # the pair's own, around the slope (0: the slope)
    late_ratio: float = 1.25  # a gap is read as a late time stamp when that explains this many times the coincidences


@dataclass
class TurnResult:
    t_s: float  # boundary time (first beam of the newer turn), s since the first beam
    v_mps: float
    w_radps: float
    cov: np.ndarray  # 2x2 over (v, w), after the filter
    pose: tuple[float, float, float]
    measured: VelocityEstimate | None
    degraded: bool
    searched: bool
    clock_offset_s: float = 0.0  # time stamp of the turn minus its time on the turn clock (>= 0: stamped late)


class DistortionCore:
    """State of one odometry run on plain values (used by the component, tests and bench)."""

    def __init__(self, config: DistortionConfig | None = None, pose0: tuple[float, float, float] = (0.0, 0.0, 0.0)):
        self.cfg = config or DistortionConfig()
        self.prev: Echoes | None = None
        self.prev_t0: float | None = None
        self.kf: KalmanFilter | None = None
        self.t_kf: float | None = None
        self.pose = pose0
        self.last_vw: tuple[float, float] | None = None
        self.recent_scores: list[int] = []
        self.turns = self.degraded = self.searches = self.wide_searches = self.resets = 0
        self.seconds = 0.0  # CPU time of step (this thread's)
        self.first_s: float | None = None  # ... of the first step with a result
        self.split_s = {"echoes": 0.0, "estimate": 0.0, "search": 0.0}  # CPU time of its stages
        # turn clock: a turn's time stamp may come late (a logger that stalls, then catches up)
        self.clock_offset_s = 0.0  # stamp minus turn-clock time of the newest turn
        self.prev_clock_s: float | None = None  # turn-clock time of the previous turn's first beam
        self.intervals: list[float] = []  # recent stamp intervals of one turn (rotation period)
        self.late_stamps = self.missing_turns = 0
        self.beam_times_s = np.zeros(0)  # the newest turn's beams on the turn clock
        self.up_rel_db = np.zeros((0, 0), np.float32)  # its up image in dB above the beam medians
        self.yaw_acc = 0.0  # rad/s^2, from the last two turns' yaw rates
        self.w_hist: list[tuple[float, float]] = []  # (turn-clock time, filtered yaw rate) of the last turns

    def _sigma_r(self, config) -> float:
        return self.cfg.sigma_range_m or 0.5 * config.range_resolution_m

    def _new_filter(self, v: float, w: float, cov: np.ndarray) -> KalmanFilter:
        from filterpy.kalman import (
            KalmanFilter,  # here, not at import (scipy.stats: 0.5-0.8 s); the component loads it in start()
        )

        kf = KalmanFilter(dim_x=3, dim_z=2)
        kf.x = np.array([v, 0.0, w])
        kf.P = np.diag([cov[0, 0], self.cfg.accel_std_mps2 ** 2, cov[1, 1]])
        kf.H = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
        return kf

    def _predict(self, t_s: float) -> None:
        dt = t_s - self.t_kf
        c = self.cfg
        self.kf.F = np.array([[1.0, dt, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        qj = c.accel_std_mps2 ** 2  # white jerk spectral density (m^2/s^5 per s)
        self.kf.Q = np.array([[qj * dt ** 3 / 3, qj * dt ** 2 / 2, 0.0],
                              [qj * dt ** 2 / 2, qj * dt, 0.0],
                              [0.0, 0.0, c.yaw_accel_std_radps2 ** 2 * dt]])
        self.kf.predict()
        self.t_kf = t_s

    def step(self, t_s: np.ndarray, azimuth_rad: np.ndarray, up: np.ndarray, down: np.ndarray | None,
             config) -> TurnResult | None:
        """One complete turn (beam times in s from a fixed origin). None for the first turn."""
        t0 = time.thread_time()
        r = None
        try:
            r = self._step(t_s, azimuth_rad, up, down, config)
            return r
        finally:
            dt = time.thread_time() - t0
            self.seconds += dt
            if r is not None and self.first_s is None:
                self.first_s = dt  # the first registration: a search of the whole speed and yaw-rate range

    def _period(self, config) -> float:
        """Rotation period: the median of the recent one-turn stamp intervals (the configured
        rate until there are 8)."""
        if len(self.intervals) >= 8:
            return float(np.median(self.intervals))
        return 1.0 / config.rotation_hz

    def _clock(self, prev: Echoes | None, echoes: Echoes, t_stamp: float, beta: float, config) -> float:
        """Offset (stamp minus turn clock) of the new turn. The radar turns at a steady rate;
        its time stamps may come late: a logger stalls, then catches up with intervals shorter
        than a turn (RADIATE: stalls of up to 1.6 s). A gap of n turns between stamps is either
        n - 1 missing turns or a late stamp: the hypothesis kept is the one whose times make
        the two turns' echoes coincide at the filter's prediction (at rest they all do, and the
        stamps are kept). After a late stamp, the clock runs a turn per turn until the stamps
        have caught up."""
        offset = self.clock_offset_s
        if prev is None or self.prev_clock_s is None:
            return 0.0
        period = self._period(config)
        gap = t_stamp - offset - self.prev_clock_s  # interval on the turn clock if the offset holds
        n = max(1, int(round(gap / period)))
        if n == 1:
            if offset == 0.0 and 0.5 * period < gap < 1.5 * period:
                self.intervals = (self.intervals + [gap])[-64:]
            return max(0.0, offset - max(period - gap, 0.0))  # catching up: a turn per turn
        if self.kf is not None:
            scores = []
            x = self.kf.x
            for m in range(1, n + 1):
                dt_m = m * period if m < n else gap
                shift = offset + gap - dt_m
                t_m = self.prev_clock_s + dt_m
                shifted = Echoes(echoes.t_s - shift, echoes.azimuth_rad, echoes.range_m, echoes.ramp, echoes.snr_db)
                dt_kf = t_m - self.t_kf
                scores.append(self._score(prev, shifted, t_m, beta, float(x[0] + x[1] * dt_kf), float(x[2]),
                                          float(x[1])))
            m = int(np.argmax(scores[:-1])) + 1
            if scores[m - 1] >= self.cfg.late_ratio * scores[-1] + 3:
                self.late_stamps += 1
                return offset + gap - m * period
        self.missing_turns += n - 1
        return offset

    def _step(self, t_s, azimuth_rad, up, down, config) -> TurnResult | None:  # type: ignore[no-untyped-def]
        c = self.cfg
        t_s = np.asarray(t_s, float)
        t0, span = float(np.min(t_s)), float(np.ptp(t_s))
        full = self._period(config) * (len(t_s) - 1) / config.beams_per_turn
        if 0.0 < span < 0.98 * full:
            # a turn lasts a rotation: beams squeezed between two stamps (a log catching up with
            # itself, its beams spread up to the next stamp on import) are spread over one
            t_s = t0 + (t_s - t0) * (full / span)
        tc = time.thread_time()
        rel: list[np.ndarray] = []
        echoes = extract_echoes(t_s, azimuth_rad, up, down, config, c.echoes, up_rel_db=rel)
        self.up_rel_db = rel[0]
        self.split_s["echoes"] += time.thread_time() - tc
        beta = doppler_beta_s(config) if c.doppler else 0.0
        prev = self.prev
        self.clock_offset_s = self._clock(prev, echoes, float(np.min(t_s)), beta, config)
        if self.clock_offset_s:
            echoes.t_s = echoes.t_s - self.clock_offset_s
        t_ref = t0 - self.clock_offset_s
        self.beam_times_s = t_s - self.clock_offset_s
        self.prev, self.prev_clock_s = echoes, t_ref
        if prev is None:
            return None
        sr = self._sigma_r(config)
        kw = dict(beta_s=beta, gate_m=c.gate_m, sigma_range_m=sr, sigma_azimuth_rad=c.sigma_azimuth_rad,
                  min_pairs=c.min_pairs)
        around = None
        if self.kf is not None:
            self._predict(t_ref)
            around = (float(self.kf.x[0]), float(self.kf.x[2]))
        acc = 0.0 if self.kf is None else float(self.kf.x[1])
        # the yaw acceleration is modelled where it shows: when at its largest it would turn the
        # scene by more than a beam width over a turn (1 Hz IMPALA: yes; 4 Hz Navtech: 16 x less, no)
        period = self._period(config)
        turning = c.yaw_accel and 0.5 * c.max_yaw_accel_radps2 * period ** 2 > config.beam_width_rad
        yacc = self.yaw_acc if turning else 0.0
        kw["yaw_accel_radps2"] = yacc
        kw["yaw_accel_std_radps2"] = c.yaw_accel_prior_std_radps2 if turning else 0.0
        est, searched = None, False
        if around is not None and self.recent_scores:
            # the prediction first: kept when its result coincides as well as the last turns did
            tc = time.thread_time()
            est = estimate_velocity(prev, echoes, around[0], around[1], t_ref, accel_mps2=acc, **kw)
            self.split_s["estimate"] += time.thread_time() - tc
            if est is not None:
                score = self._score(prev, echoes, t_ref, beta, est.v_mps, est.w_radps, acc, yacc)
                if score >= c.accept_ratio * float(np.median(self.recent_scores)):
                    self.recent_scores = (self.recent_scores + [score])[-8:]
                else:
                    est = None
        if est is None:
            searched = True
            tc = time.thread_time()
            start = self._search(prev, echoes, t_ref, beta, around, acc, yacc)
            if around is not None and (start is None or (self.recent_scores and start[2] < c.lost_ratio * float(
                    np.median(self.recent_scores)))):
                # few coincidences near the prediction: the filter may be lost; search everything
                wide = self._search(prev, echoes, t_ref, beta, None, acc, yacc)
                if wide is not None and (start is None or wide[2] > start[2]):
                    start = wide
                    self.wide_searches += 1
            self.split_s["search"] += time.thread_time() - tc
            if start is not None:
                self.recent_scores = (self.recent_scores + [start[2]])[-8:]
                tc = time.thread_time()
                est = estimate_velocity(prev, echoes, start[0], start[1], t_ref, accel_mps2=acc, **kw)
                self.split_s["estimate"] += time.thread_time() - tc
        self.searches += searched
        degraded = est is None
        if est is not None:
            if self.kf is None:
                self.kf = self._new_filter(est.v_mps, est.w_radps, est.cov)
                self.t_kf = t_ref
            else:
                self._update(est)
        elif self.kf is None:
            self.degraded += 1
            self.turns += 1
            return TurnResult(t_ref, math.nan, math.nan, np.full((2, 2), math.inf), self.pose, None, True, searched,
                              self.clock_offset_s)
        self.degraded += degraded
        v, w = float(self.kf.x[0]), float(self.kf.x[2])
        P = self.kf.P
        cov = np.array([[P[0, 0], P[0, 2]], [P[2, 0], P[2, 2]]])
        if self.last_vw is not None and self.prev_t0 is not None:
            vm, wm = 0.5 * (self.last_vw[0] + v), 0.5 * (self.last_vw[1] + w)
            x, y, th = arc_step(*self.pose, vm, wm, t_ref - self.prev_t0)
            self.pose = (x, y, math.remainder(th, 2.0 * math.pi))
        # yaw acceleration for the next pair's motion model: slope of the yaw rates over the last
        # turns (at least two, yaw_accel_window_s), none at walking pace (a car turns as it rolls)
        hist = (self.w_hist + [(t_ref, w)])[-8:]
        self.w_hist = [h for h in hist[:-2] if t_ref - h[0] <= c.yaw_accel_window_s] + hist[-2:]
        self.yaw_acc = 0.0
        if abs(v) >= 1.0 and len(self.w_hist) >= 2:
            tw, ww = np.array(self.w_hist).T
            lim = c.max_yaw_accel_radps2
            self.yaw_acc = float(np.clip(np.polyfit(tw - tw[-1], ww, 1)[0], -lim, lim))
        self.last_vw, self.prev_t0 = (v, w), t_ref
        self.turns += 1
        return TurnResult(t_ref, v, w, cov, self.pose, est, degraded, searched, self.clock_offset_s)

    def _nis(self, est: VelocityEstimate) -> float:
        kf = self.kf
        y = np.array([est.v_mps, est.w_radps]) - kf.H @ kf.x
        s = kf.H @ kf.P @ kf.H.T + est.cov
        return float(y @ np.linalg.solve(s, y))

    def _update(self, est: VelocityEstimate) -> None:
        if self._nis(est) > self.cfg.reset_nis:
            # supported by the coincidences but far from the prediction (a sudden stop, a
            # wrong filter after a loss): start the filter again from the measurement
            self.resets += 1
            self.kf = self._new_filter(est.v_mps, est.w_radps, est.cov)
            return
        self.kf.update(np.array([est.v_mps, est.w_radps]), R=est.cov)

    def _search(self, ea: Echoes, eb: Echoes, t_ref: float, beta: float,
                around: tuple[float, float] | None, acc: float, yacc: float = 0.0) -> tuple[float, float, int] | None:
        c = self.cfg
        v_lo, v_hi = -c.max_reverse_mps, c.max_speed_mps
        w_lo, w_hi = -c.max_yaw_rate_radps, c.max_yaw_rate_radps
        prior = None
        if around is not None:  # +-3 sigma of the prediction, within [1, 3] m/s and [3, 12] deg/s
            P = self.kf.P
            sv = min(max(3.0 * math.sqrt(P[0, 0]), 1.0), 3.0)
            sw = min(max(3.0 * math.sqrt(P[2, 2]), math.radians(3.0)), math.radians(12.0))
            cv, cw = min(max(around[0], v_lo), v_hi), min(max(around[1], w_lo), w_hi)
            v_lo, v_hi = max(v_lo, cv - sv), min(v_hi, cv + sv)
            w_lo, w_hi = max(w_lo, cw - sw), min(w_hi, cw + sw)
            prior = (around[0], around[1], np.array([[P[0, 0], P[0, 2]], [P[2, 0], P[2, 2]]]))
        return search_velocity(ea, eb, t_ref, beta, (v_lo, v_hi), (w_lo, w_hi), c.search_v_step,
                               c.search_w_step, c.search_gate_m, prior=prior, accel_mps2=acc, yaw_accel_radps2=yacc)

    def _score(self, ea: Echoes, eb: Echoes, t_ref: float, beta: float, v: float, w: float, acc: float,
               yacc: float = 0.0) -> int:
        r = search_velocity(ea, eb, t_ref, beta, (v, v), (w, w), 1.0, 1.0, self.cfg.search_gate_m, accel_mps2=acc,
                            yaw_accel_radps2=yacc)
        return 0 if r is None else r[2]

    def beam_poses(self, t_s: np.ndarray, t_from: float, pose_from: tuple[float, float, float],
                   v: float, w: float) -> np.ndarray:
        """Poses (n, 3) of beams at ``t_s`` on the arc (v, w) from ``pose_from`` at ``t_from``."""
        dx, dy, dth = arc_poses(v, w, np.asarray(t_s) - t_from)
        x0, y0, th0 = pose_from
        c, s = math.cos(th0), math.sin(th0)
        return np.column_stack([x0 + c * dx - s * dy, y0 + s * dx + c * dy, th0 + dth])
