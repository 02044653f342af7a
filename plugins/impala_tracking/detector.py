"""``tracking.MoverDetector``: moving objects from the Doppler of paired detections (seed 1 §4.3.2).

The fuzzy pairer has already compared the up- and down-ramp spectra of every beam: a pair
whose peaks sit ``2 f_d`` apart (eq. 3) has radial speed ``V``. A static target seen from a
radar moving forward at ``s`` has ``V_static = -s cos(theta) cos(el)`` (seed 1 eq. 7, the
depression factor ``cos el`` = ground / slant range for ground echoes, 1 for raised ones), so
removing the ego-Doppler leaves the ground-relative radial speed

    v_g = V - V_static = u . v_target                                  (u: line of sight)

which is zero for the static world. A detection is a mover candidate when ``|v_g|`` exceeds
``n_sigma`` times its standard deviation ``sqrt(sigma_D^2 + (cos theta sigma_s)^2)`` (Doppler
measurement noise, ego-speed uncertainty) and ``min_radial_speed_mps``; under both height
hypotheses (ground, raised) when the radar moves. Candidates of adjacent beams with close
range and Doppler are one object (a car spans its beam width, several beams): clustered
(``scipy.sparse.csgraph.connected_components``) into one detection with amplitude-weighted
range, azimuth, Doppler and time. False detections are filtered by a minimum amplitude, a
clutter map (cells where candidates keep appearing: persistent ghost pairs, fluttering
vegetation) and optionally persistence (a candidate near the previous turn's). Each
detection carries its position and radial-speed covariances, in the frame of the ``pose``
input (map frame from RTK-GPS or odometry; the radar's own frame without it).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from impala_flow import Component, Input, Output, Param
from impala_flow.msgs import Pose2D
from impala_msgs import RadarDetections, Speed

from .types import MoverDetections

__all__ = ["MoverDetector", "ground_radial_speed_mps", "cluster_candidates", "absorb_ghosts", "ClutterMap"]


def ground_radial_speed_mps(radial_mps, azimuth_rad, range_m, speed_mps: float,
                            radar_height_m: float = 1.3) -> tuple[np.ndarray, np.ndarray]:
    """Ego-Doppler removed (eq. 7): ``(v_raised, v_ground)`` = V + s cos(theta) f, f = 1 for a
    raised scatterer, ground / slant range for a ground one (NaN nearer than the height)."""
    v = np.asarray(radial_mps, float)
    c = speed_mps * np.cos(np.asarray(azimuth_rad, float))
    r = np.asarray(range_m, float)
    ratio = np.divide(radar_height_m, r, out=np.full(r.shape, np.inf), where=r > 0)
    f_ground = np.sqrt(np.clip(1.0 - ratio**2, 0.0, None))
    return v + c, v + c * f_ground


def cluster_candidates(beam: np.ndarray, range_m: np.ndarray, v_mps: np.ndarray, n_beams: int,
                       max_beam_gap: int, max_range_gap_m: float, max_speed_gap_mps: float) -> np.ndarray:
    """Label of each candidate: connected components of 'adjacent beams (circular), close range
    and close Doppler'."""
    n = len(beam)
    if n == 0:
        return np.zeros(0, np.int64)
    db = np.abs(beam[:, None] - beam[None, :])
    db = np.minimum(db, n_beams - db)
    near = ((db <= max_beam_gap) & (np.abs(range_m[:, None] - range_m[None, :]) <= max_range_gap_m)
            & (np.abs(v_mps[:, None] - v_mps[None, :]) <= max_speed_gap_mps))
    i, j = np.nonzero(near)
    _, labels = connected_components(coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n)), directed=False)
    return labels


def absorb_ghosts(labels: np.ndarray, range_m: np.ndarray, azimuth_rad: np.ndarray, weight: np.ndarray,
                  radius_m: float, max_beams: int) -> np.ndarray:
    """Cluster each cluster merges into: a cluster of at most ``max_beams`` detections within
    ``radius_m`` (range and arc) of one with at least twice as many (and 3 or more) is a ghost
    pair of that object's peaks (front and rear of a car paired crosswise, seed 1 §2.4): its
    position still belongs to the object, its Doppler does not. Others map to themselves."""
    n = int(labels.max()) + 1
    cnt = np.bincount(labels, minlength=n)
    wsum = np.bincount(labels, weight, n)
    r = np.bincount(labels, weight * range_m, n) / wsum
    az = np.arctan2(np.bincount(labels, weight * np.sin(azimuth_rad), n),
                    np.bincount(labels, weight * np.cos(azimuth_rad), n))
    target = np.arange(n)
    big = cnt >= 3
    for i in np.nonzero(cnt <= max_beams)[0]:
        arc = np.abs(np.angle(np.exp(1j * (az - az[i])))) * r[i]
        c = np.nonzero(big & (cnt >= 2 * cnt[i]) & (np.abs(r - r[i]) <= radius_m) & (arc <= radius_m))[0]
        if len(c):
            target[i] = c[np.argmax(cnt[c])]
    return target


class ClutterMap:
    """Rate of mover candidates per cell of ``cell_m`` in the detection frame, forgotten with
    time constant ``tau_turns``: cells above ``threshold`` candidates per turn are clutter."""

    def __init__(self, cell_m: float, tau_turns: float, threshold: float) -> None:
        self.cell_m, self.decay, self.threshold = cell_m, 1.0 - 1.0 / tau_turns, threshold
        self.rate: dict[tuple[int, int], float] = {}

    def is_clutter(self, xy_m: np.ndarray) -> np.ndarray:
        keys = np.floor(np.asarray(xy_m).reshape(-1, 2) / self.cell_m).astype(np.int64)
        return np.array([self.rate.get((int(a), int(b)), 0.0) > self.threshold for a, b in keys], bool)

    def update(self, xy_m: np.ndarray) -> None:
        self.rate = {k: v * self.decay for k, v in self.rate.items() if v * self.decay > 1e-3}
        w = 1.0 / self.decay if self.decay > 0 else 1.0
        for a, b in np.floor(np.asarray(xy_m).reshape(-1, 2) / self.cell_m).astype(np.int64):
            k = (int(a), int(b))
            self.rate[k] = self.rate.get(k, 0.0) + (1.0 - self.decay) * w


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
