"""``slam.EkfSlam``: trajectory-oriented EKF-SLAM with Fourier-Mellin registration and loop
closure (seed 2, §IV-VI). The filter itself is :class:`impala_slam.ekf_slam.core.PoseEkf`.

Per radar image (one turn):

1. **Prediction / augmentation**: the new pose is the last one composed with the odometry
   increment since the previous image (``Grid.pose`` from the panoramic builder's odometer
   and gyro, or the ``odometry`` input, e.g. ``slam.DistortionOdometry``'s pose; without
   either, the last increment again), with the covariance Q of that increment:
   sigma_xy = odo_sigma_m + odo_sigma_frac |d|, sigma_theta = odo_sigma_deg +
   odo_sigma_rot_frac |dtheta| (independent per step: the odometer's scale error and the
   gyro's bias are not white, which is why Q is wider than their noise).
2. **Registration** with the previous image: the FMT transform and its covariance (from
   the ``registration`` input, i.e. ``slam.FmtRegistration`` upstream, or computed here
   with ``registrations: internal``); an EKF update of T_{n-1,n}, gated by chi^2 (3 dof)
   so a wrong registration never enters. With ``register_last`` > 1 the image is also
   registered with the few images before (more constraints, more FMT time).
3. **Loop closure**: keyframes (an image kept every ``keyframe_m`` of travel) at least
   ``loop_min_travel_m`` back along the path whose predicted distance to the current pose
   is within ``loop_radius_m`` at the Mahalanobis gate (chi^2 2 dof, 99 %) are candidates,
   nearest (in Mahalanobis distance) first; up to ``loop_candidates`` per turn are
   registered by FMT and accepted when the innovation passes ``loop_chi2`` (3 dof): an EKF
   update that moves the whole trajectory. The FMT covariance of a loop registration is
   multiplied by ``loop_cov_scale`` (2): two views minutes and metres apart differ more than
   consecutive turns (on campus-loop seeds 2009 and 11 the accepted closures had a mean NEES
   of 5 and 13 against the truth with the consecutive turns' covariance; 1, 2 and 4 gave
   trajectories within 3 % of each other on seeds 2009, 11 and 12). Candidates refused by the gate are counted (and
   emitted as ``loop_rejected`` constraints, so a pose graph downstream can be shown them).

Outputs: ``pose`` each turn (the newest pose, covariance its 3x3 block), ``trajectory``
every ``trajectory_period_s`` and at the end (every pose after the last update), ``map``
every ``map_period_s`` and at the end (the keyframes' dB images placed at their current
poses: the global map of the seed's Figs. 5 and 7), ``constraints`` (every odometry
increment, registration and loop closure as ``RelativePose2D``, for ``slam.PoseGraph``).
The map frame is the first pose (0, 0, 0), as in the seed's comparison.

A turn it can do nothing with (an image with no cell above the threshold: silent or
all-zero beams) still gives a pose, carried by the odometry (its registrations fail and
are counted); the summary counts it as ``empty_images``, and a map whose keyframes are all
empty is not emitted (``empty_maps``).
"""

from __future__ import annotations

import math
import time
from collections import deque
from typing import Any

import numpy as np

from impala_flow import Input, OutOfHistory, Output, Param, Periodic
from impala_flow.msgs import Grid, Pose2D, RelativePose2D, Trajectory2D

from ..fmt.component import UNKNOWN_COV, FmtComponent
from ..fmt.core import FmtImage, FmtParams, polar_spectrum, prepare, register, warm_up
from ..fmt.parallel import TaskPool
from ..se2 import between
from ..tilemap import TileMap, warp_grid_to_map
from .core import PoseEkf

__all__ = ["EkfSlam"]

Pose = tuple[float, float, float]

CHI2_2DOF_99 = 9.21
#: keyframes are kept as uint8 steps of this many dB (0-63.75 dB over the threshold): a
#: quarter of float32's memory (400 x 400 cells: 160 kB a keyframe)
KEYFRAME_DB_STEP = 0.25


def _quantise(img: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(img / KEYFRAME_DB_STEP), 0, 255).astype(np.uint8)


def _dequantise(q: np.ndarray) -> np.ndarray:
    return q.astype(np.float32) * np.float32(KEYFRAME_DB_STEP)


class EkfSlam(FmtComponent):
    """Trajectory-oriented EKF-SLAM with FMT registrations and loop closures (seed 2).

    Every pose is in the state; registrations of consecutive images and of old keyframes
    (loop closures) are its observations (see the module docstring)."""

    pose = Output(Pose2D, doc="newest pose in the map frame, with its 3x3 covariance")
    trajectory = Output(Trajectory2D, doc="every pose after the last update")
    map = Output(Grid, doc="keyframe images (dB over the threshold) placed at their estimated poses")
    constraints = Output(RelativePose2D, doc="odometry, registrations and loop closures (for slam.PoseGraph)")
    trajectory_timer = Periodic("trajectory_period_s")
    map_timer = Periodic("map_period_s")

    registrations = Param(str, default="input", choices=("input", "internal"),
                         doc="consecutive registrations from the 'registration' input (slam.FmtRegistration) "
                             "or computed here")
    trajectory_period_s = Param(float, default=10.0, gt=0, doc="period of the trajectory output (s)")
    map_period_s = Param(float, default=60.0, gt=0, doc="period of the map output (s)")
    odo_sigma_m = Param(float, default=0.05, ge=0, doc="odometry: translation std per step (m)")
    odo_sigma_frac = Param(float, default=0.03, ge=0, doc="odometry: translation std per metre travelled")
    odo_sigma_deg = Param(float, default=0.5, ge=0, doc="odometry: heading std per step (deg)")
    odo_sigma_rot_frac = Param(float, default=0.03, ge=0, doc="odometry: heading std per radian turned")
    register_last = Param(int, default=1, ge=1,
                          doc="register each image with this many previous images (1: the previous one only)")
    odometry_wait = Param(int, default=4, ge=0,
                          doc="images held at most while the odometry input catches up with their time")
    registration_chi2 = Param(float, default=16.27, gt=0,
                              doc="consecutive registrations beyond this chi^2 (3 dof) are refused")
    keyframe_m = Param(float, default=4.0, gt=0, doc="travel between two images kept for loop closure")
    loop_min_travel_m = Param(float, default=60.0, gt=0, doc="a loop candidate lies at least this far back")
    loop_radius_m = Param(float, default=15.0, gt=0, doc="poses nearer than this see the same scene")
    loop_candidates = Param(int, default=2, ge=0, doc="candidates registered per turn (0: no loop closure)")
    loop_chi2 = Param(float, default=11.34, gt=0, doc="innovation gate of a loop closure (chi^2, 3 dof)")
    loop_cov_scale = Param(float, default=2.0, ge=1,
                           doc="loop registrations: covariance x this (views metres and minutes apart)")
    loop_min_snr = Param(float, default=8.0, gt=0, doc="loop registrations with a weaker peak are refused")
    threads = Param(int, default=2, ge=1, le=4,
                    doc="threads of each FMT registration (as slam.FmtRegistration's): the same results with any "
                        "number, less wall time")

    @classmethod
    def declare_ports(cls, params: dict[str, Any]) -> tuple[dict[str, Input], dict[str, Output]]:
        ins = dict(cls.__inputs__)
        outs = dict(cls.__outputs__)
        if params.get("registrations", "input") == "input":
            ins["image"] = Input(Grid, sync="turn", maxsize=64, doc="panoramic image, vehicle frame, pose = odometry")
            ins["registration"] = Input(RelativePose2D, sync="turn", maxsize=64,
                                        doc="FMT transform from the previous image (slam.FmtRegistration)")
        else:
            ins["image"] = Input(Grid, maxsize=64, doc="panoramic image, vehicle frame, pose = odometry")
        ins["odometry"] = Input(Pose2D, policy="sampling", history=10.0, required=False,
                                doc="odometry pose (instead of the image's), e.g. slam.DistortionOdometry")
        return ins, outs

    def start(self) -> None:
        self.params_fmt: FmtParams = self.fmt_params()
        self._pool = TaskPool(self.threads)
        warm_up()  # FMT's compiled loop loaded here, not in the first turn
        self.ekf: PoseEkf | None = None
        self.t_ns: list[int] = []
        self._index: dict[int, int] = {}  # image time -> pose index
        self.travel_m: list[float] = []
        self.keyframes: dict[int, np.ndarray] = {}  # pose index -> registration image (uint8 dB steps)
        self._prev: FmtImage | None = None
        self._recent: list[tuple[int, FmtImage]] = []  # (pose index, image) of the last register_last images
        self._prev_odom: Pose | None = None
        self._pending: deque[tuple[int, Grid, RelativePose2D | None]] = deque()  # images waiting for odometry
        self.counts = dict(turns=0, empty_images=0, empty_maps=0, registrations=0, registration_failures=0,
                           registrations_refused=0,
                           loop_candidates_tried=0, loop_closures=0, loop_rejected_gate=0, loop_rejected_weak=0,
                           no_odometry=0, registrations_unmatched=0)
        self.fmt_s = 0.0
        self.filter_s = 0.0
        self.step_ms: list[tuple[int, float]] = []  # (poses, ms of the whole step)

    # --- per turn ----------------------------------------------------------------------
    def process(self, t: int) -> None:
        if self.trigger == "trajectory_timer":
            if self.ekf is not None:
                self._emit_trajectory(t)
            return
        if self.trigger == "map_timer":
            self._emit_map(t)
            return
        grid: Grid = self.inputs["image"].take()
        reg: RelativePose2D | None = self.inputs["registration"].take() if "registration" in self.inputs else None
        self._pending.append((t, grid, reg))
        self._drain(final=False)

    def _drain(self, final: bool) -> None:
        """Process the waiting images whose odometry has arrived. An odometry stream is
        often stamped before it is produced (DistortionOdometry stamps a turn's motion at
        its start, a turn later): an image waits until the odometry passes its time, at most
        ``odometry_wait`` images (then it goes without, counted)."""
        port = self.inputs["odometry"]
        while self._pending:
            t, grid, reg = self._pending[0]
            if port.connected and not final and len(self._pending) <= self.odometry_wait:
                last = port.latest()
                if last is None or last.timestamp < t:
                    return
            self._pending.popleft()
            self._turn(t, grid, reg)

    def _turn(self, t: int, grid: Grid, reg: RelativePose2D | None) -> None:
        t_step = time.perf_counter()
        inc = self._increment(t, grid)
        t0 = time.perf_counter()
        cur = prepare(grid, self.params_fmt, self.linear_power, workers=self._pool.threads, pool=self._pool)
        self.fmt_s += time.perf_counter() - t0
        self.counts["turns"] += 1
        if not np.any(cur.image > 0):  # nothing above the threshold: its registrations will fail
            self.counts["empty_images"] += 1
        if self.ekf is None:
            self.ekf = PoseEkf()
            self._after_step(t, cur, grid, t_step)
            return
        ekf = self.ekf
        # 1. augmentation by the odometry increment
        guessed = inc is None
        if guessed:  # no odometry: constant velocity, the last estimated increment again
            self.counts["no_odometry"] += 1
            inc = ekf.relative_pose(ekf.n - 2, ekf.n - 1) if ekf.n >= 2 else (0.0, 0.0, 0.0)
        q = self._odometry_cov(inc, no_odometry=guessed)
        t0 = time.perf_counter()
        j = ekf.augment(inc, q)
        self.filter_s += time.perf_counter() - t0
        self.constraints.emit(t, RelativePose2D(self.t_ns[-1], t, *inc, q, "odometry"))
        # 2. registration with the previous image
        i = j - 1
        if reg is None or reg.kind == "start":
            t0 = time.perf_counter()
            r = register(self._prev, cur, self.params_fmt, prior_theta_rad=inc[2], pool=self._pool)
            self.fmt_s += time.perf_counter() - t0
            z, rcov, ok = r.xyt, r.cov_xyt, r.ok
        else:
            z, rcov, ok = (reg.x_m, reg.y_m, reg.theta_rad), np.asarray(reg.cov_xyt), reg.kind == "registration"
            if reg.from_t_ns != self.t_ns[-1]:  # an image the registration saw and this filter did not
                found = self._index.get(reg.from_t_ns)
                if found is None:
                    self.counts["registrations_unmatched"] += 1
                    self.log.warning("registration from t=%d ns matches no pose (t=%d ns): ignored",
                                     reg.from_t_ns, t)
                    ok = False
                else:
                    i = found
        if ok:
            self._observe(i, j, z, rcov, t, self.registration_chi2, "registration")
        else:
            self.counts["registration_failures"] += 1
            self.constraints.emit(t, RelativePose2D(self.t_ns[-1], t, 0.0, 0.0, 0.0, UNKNOWN_COV.copy(), "failed"))
        # ... and optionally with the few before it
        for i, older in self._recent[:-1]:
            t0 = time.perf_counter()
            r = register(older, cur, self.params_fmt, prior_theta_rad=ekf.relative_pose(i, j)[2], pool=self._pool)
            self.fmt_s += time.perf_counter() - t0
            if r.ok:
                self._observe(i, j, r.xyt, r.cov_xyt, t, self.registration_chi2, "registration")
            else:
                self.counts["registration_failures"] += 1
        self._after_step(t, cur, grid, t_step, inc)
        # 3. loop closure
        if self.loop_candidates > 0:
            self._close_loops(t, j, cur)
        self.step_ms[-1] = (self.step_ms[-1][0], 1e3 * (time.perf_counter() - t_step))
        x, y, th = ekf.pose(j)
        self.pose.emit(t, Pose2D(x, y, th, ekf.cov(j), "map"))

    def _after_step(self, t: int, cur: FmtImage, grid: Grid, t_step: float,
                    inc: Pose | None = None) -> None:
        ekf = self.ekf
        assert ekf is not None
        j = ekf.n - 1
        self.t_ns.append(t)
        self._index[t] = j
        step = 0.0 if inc is None else math.hypot(inc[0], inc[1])
        self.travel_m.append((self.travel_m[-1] if self.travel_m else 0.0) + step)
        gp = grid.pose
        self._prev_odom = None if gp is None else (gp.x_m, gp.y_m, gp.theta_rad)
        self._prev = cur
        self._recent = [*self._recent, (j, cur)][-self.register_last:]
        last_kf = max(self.keyframes) if self.keyframes else None
        if last_kf is None or self.travel_m[j] - self.travel_m[last_kf] >= self.keyframe_m:
            self.keyframes[j] = _quantise(cur.image)
        self.step_ms.append((ekf.n, 1e3 * (time.perf_counter() - t_step)))
        if j == 0:
            x, y, th = ekf.pose(0)
            self.pose.emit(t, Pose2D(x, y, th, ekf.cov(0), "map"))

    def _increment(self, t: int, grid: Grid) -> Pose | None:
        """The odometry's motion since the previous image: the ``odometry`` input at both
        image times when it is connected, else the two images' own poses; None if missing."""
        port = self.inputs["odometry"]
        if port.latest() is not None:
            if not self.t_ns:
                return None
            try:
                a, b = port.at(self.t_ns[-1]), port.at(t)
            except OutOfHistory:  # the odometry stopped, lags or started late: this turn goes without
                return None
            return between((a.x_m, a.y_m, a.theta_rad), (b.x_m, b.y_m, b.theta_rad))
        if grid.pose is None or self._prev_odom is None:
            return None
        return between(self._prev_odom, (grid.pose.x_m, grid.pose.y_m, grid.pose.theta_rad))

    def _odometry_cov(self, inc: Pose, no_odometry: bool) -> np.ndarray:
        d = math.hypot(inc[0], inc[1])
        s_xy = self.odo_sigma_m + self.odo_sigma_frac * d
        s_th = math.radians(self.odo_sigma_deg) + self.odo_sigma_rot_frac * abs(inc[2])
        if no_odometry:  # a guess (the last increment again): wide enough for a start or a stop
            s_xy, s_th = s_xy + 2.0 + 0.5 * d, s_th + math.radians(10.0)
        return np.diag([s_xy ** 2, s_xy ** 2, s_th ** 2])

    def _observe(self, i: int, j: int, z: Pose, r: np.ndarray, t: int, gate: float, kind: str) -> bool:
        ekf = self.ekf
        assert ekf is not None
        _, _, chi2 = ekf.innovation(i, j, z, r)
        t_j = self.t_ns[j] if j < len(self.t_ns) else t  # j is the newest pose: not listed yet
        if not math.isfinite(chi2) or chi2 > gate:
            self.counts["registrations_refused" if kind == "registration" else "loop_rejected_gate"] += 1
            self.constraints.emit(t, RelativePose2D(self.t_ns[i], t_j, *z, r, f"{kind}_rejected"))
            return False
        t0 = time.perf_counter()
        ekf.update(i, j, z, r)
        self.filter_s += time.perf_counter() - t0
        self.counts["registrations" if kind == "registration" else "loop_closures"] += 1
        self.constraints.emit(t, RelativePose2D(self.t_ns[i], t_j, *z, r, kind))
        return True

    def _close_loops(self, t: int, j: int, cur: FmtImage) -> None:
        ekf = self.ekf
        assert ekf is not None
        far = [k for k in self.keyframes if self.travel_m[j] - self.travel_m[k] >= self.loop_min_travel_m]
        if not far:
            return
        idx = np.array(far)
        z, cov = ekf.relative(idx, j)
        s = cov[:, :2, :2] + np.eye(2) * self.loop_radius_m ** 2
        m2 = np.einsum("ki,kij,kj->k", z[:, :2], np.linalg.inv(s), z[:, :2])
        order = np.argsort(m2)
        for o in order[: self.loop_candidates]:
            if m2[o] > CHI2_2DOF_99:
                break
            i = int(idx[o])
            self.counts["loop_candidates_tried"] += 1
            t0 = time.perf_counter()
            img = _dequantise(self.keyframes[i])
            old = FmtImage(img, polar_spectrum(img, self.params_fmt), self.params_fmt.cell_m)
            r = register(old, cur, self.params_fmt, prior_theta_rad=float(z[o, 2]), pool=self._pool)
            self.fmt_s += time.perf_counter() - t0
            if not r.ok or r.snr_translation < self.loop_min_snr:
                self.counts["loop_rejected_weak"] += 1
                continue
            self._observe(i, j, r.xyt, r.cov_xyt * self.loop_cov_scale, t, self.loop_chi2, "loop")

    # --- outputs -------------------------------------------------------------------------
    def _emit_trajectory(self, t: int) -> None:
        ekf = self.ekf
        assert ekf is not None
        self.trajectory.emit(t, Trajectory2D(np.array(self.t_ns, np.int64), ekf.x.copy(), "map"))

    def _emit_map(self, t: int) -> None:
        """The global map, unless no keyframe holds a cell above the threshold (counted)."""
        if not self.keyframes:
            return
        m = self.global_map()
        if m is None:
            self.counts["empty_maps"] += 1
        else:
            self.map.emit(t, m)

    def global_map(self) -> Grid | None:
        """The keyframes' images placed at their current estimates (mean where they overlap);
        None when every keyframe is empty (all-zero, or no power over the threshold)."""
        ekf = self.ekf
        assert ekf is not None
        p = self.params_fmt
        tm = TileMap(p.cell_m, 64.0)
        half = p.size // 2
        for i, q in self.keyframes.items():
            g = Grid(_dequantise(q), p.cell_m, -half * p.cell_m, -half * p.cell_m, "vehicle")
            pose = ekf.pose(i)
            reach = half * p.cell_m
            ix0, iy0 = tm.index_of(pose[0] - reach, pose[1] - reach)
            n = 2 * half + 2
            w = warp_grid_to_map(g, pose, ix0, iy0, n, n, tm.cell_m, border=0.0)
            seen = (w > 0).astype(np.float32)
            tm.add(ix0, iy0, w, seen)
        return None if tm.empty else tm.to_grid("map")

    def flush(self, t: int) -> None:
        self._drain(final=True)
        if self.ekf is None:
            return
        self._emit_trajectory(t)
        self._emit_map(t)

    def stop(self) -> None:
        if getattr(self, "_pool", None) is not None:
            self._pool.close()

    def summary(self) -> dict:
        if getattr(self, "ekf", None) is None:
            return {}
        turns = max(1, self.counts["turns"])
        steps = [ms for _, ms in self.step_ms[1:]]
        return {**self.counts, "poses": self.ekf.n, "keyframes": len(self.keyframes),
                "fmt_ms_per_turn": round(1e3 * self.fmt_s / turns, 2),
                "filter_ms_per_turn": round(1e3 * self.filter_s / turns, 2),
                "step_ms_median": round(float(np.median(steps)), 2) if steps else 0.0,
                "step_ms_last": round(steps[-1], 2) if steps else 0.0}
