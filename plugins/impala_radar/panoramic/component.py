"""``radar.PanoramicBuilder``: one turn of beams -> RadarScan + motion-corrected Grid."""

from __future__ import annotations

from collections import deque

import cv2
import numpy as np

from impala_flow import Component, Input, Output, Param
from impala_flow.msgs import Grid, Pose2D, Twist2D, wrap_angle
from impala_msgs import RadarBeam, RadarScan, Speed, YawRate

from ..turns import TurnBuffer
from .core import (
    AzimuthTable,
    BandPool,
    doppler_compensated_power,
    grid_geometry,
    integrate_poses,
    normalise_beams,
    relative_to,
    scan_to_grid,
)

__all__ = ["PanoramicBuilder", "bootstrap_speed"]


def bootstrap_speed(first: list[tuple[int, RadarBeam]], second: list[tuple[int, RadarBeam]],
                    normalise: bool = True, cell_m: float = 0.2, range_m: float = 40.0,
                    blank_m: tuple[float, ...] = (2.0, 5.0, 10.0)) -> float:
    """Forward speed (m/s) between two turns from their uncorrected images: the scene moves
    back by the vehicle's displacement, found by phase correlation (cv2.phaseCorrelate,
    Hanning window) of the images in dB above each beam's floor, divided by the time
    between the turns' middles. Echoes that move with the vehicle (its body, the mounting,
    near multipath) pull the peak to zero: the images are tried with the near range blanked
    to each of ``blank_m`` and the clearest peak (highest response) wins (RADIATE's car
    needs 5 m). 0 when no blanking gives a clear peak."""
    polar, mids = [], []
    for buf in (first, second):
        t_ns = np.array([t for t, _ in buf], np.int64)
        power = np.array([b.up for _, b in buf], np.float32)
        power = normalise_beams(power) if normalise else power / max(float(np.median(power)), 1e-30)
        polar.append((10.0 * np.log10(np.maximum(power, np.float32(1.0))), [b.azimuth_rad for _, b in buf],
                      buf[0][1].config))
        mids.append(int(t_ns.min()) + (int(t_ns.max()) - int(t_ns.min())) // 2)
    dt_s = (mids[1] - mids[0]) * 1e-9
    best_dx, best_response = 0.0, 0.05  # below this response: no clear peak
    # each turn imaged once: without motion a cell is blanked exactly when its own range is below
    # the blanking radius (scan_to_grid's rule), so the blanked images are masks of these
    grids = []
    for db, azimuth, cfg in polar:
        grid, _ = scan_to_grid(db, azimuth, np.zeros((len(azimuth), 3)), cfg.range_per_bin_m, cell_m,
                               min(range_m, cfg.range_max_m), 0.0, cfg.range_offset_m)
        grids.append(grid.astype(np.float64))
    r_cell = grid_geometry((grids[0].shape[0] - 1) // 2, float(cell_m))[2]
    window = cv2.createHanningWindow(grids[0].shape[::-1], cv2.CV_64F)
    for blank in blank_m:
        near = r_cell < np.float32(blank)
        images = [np.where(near, 0.0, g) for g in grids]
        (dx, _), response = cv2.phaseCorrelate(images[0], images[1], window)
        if np.isfinite(dx) and np.isfinite(response) and response > best_response:
            best_dx, best_response = dx, response
    if dt_s <= 0:
        return 0.0
    return float(-best_dx * cell_m / dt_s)  # static echoes move back (-x) as the vehicle moves forward


class PanoramicBuilder(Component):
    """Collects one antenna turn into a polar image (``scan``) and a Cartesian grid
    (``image``) of ``cell_m`` cells over the radar range, each beam placed at the vehicle
    pose of its own time (seed 1 §4.1.1; see :mod:`impala_radar.panoramic.core`).

    Any beam geometry: clockwise or counter-clockwise rotation, any number of beams per
    turn, missing beams, a turn that wraps through azimuth 0, a partial first turn, and a
    partial last turn (imaged at ``flush`` when it holds ``min_turn_fraction`` of a turn).
    Range bins are placed with the beam's own ``RadarConfig`` (``range_of_bin_m``).

    Grid contract: stamped with the turn's reference time t_ref (``reference``: the turn's
    last beam, or halfway between its first and last beams in time, the time of the Oxford
    dataset's ground truth; ``scan`` is stamped the same); ``data`` float32 intensity (power, bilinear
    from the polar image; 0 where not observed), row = y, column = x, in the vehicle frame
    at t_ref (x forward, y left), the radar at the centre cell; ``origin_x_m``/
    ``origin_y_m`` the centre of cell (0, 0) (= -half extent); ``frame = "vehicle"``;
    ``pose`` the dead-reckoned pose (frame ``odom``) at t_ref, integrated continuously
    across turns, or ``None`` when no odometry is connected (the pose would only repeat
    the motion hypothesis: a SLAM then predicts with its own motion model).

    Motion during the turn, first available of: the ``odometer`` and ``gyro`` histories
    over the turn; the last estimated ``twist`` (e.g. ``slam.twist`` through a delayed
    connection: the velocity of the previous estimates, for a radar without odometry);
    the constant ``speed_mps`` / ``yaw_rate_radps``. Fed-back twist (``twist`` connected
    through a delayed connection, a feedback loop; no odometer or gyro): a complete turn waits
    for the twist of the previous image, as offline,
    where the previous turn's estimate is always back first; live, a SLAM may still be busy
    with the previous turn when this one closes (its first turns, a slow turn). The wait is
    bounded in radar time: once a beam stamped ``twist_wait_s`` after the waiting turn's last
    beam arrives, the turn is imaged with the twist it has and counted as ``stale_twist``
    (also when no estimate came for the previous image, as at a SLAM's first image, offline
    too). So a live run and its replay image the same turns the same way, bit for bit,
    whenever the live ``stale_twist`` is no larger than the replay's; while turns wait, the
    SLAM gets no new image, so a slow start drops no turn at the SLAM's input. The latency
    figures of a held turn's outputs count the wait (``Component.work_origin_ns``).
    Bootstrap: with ``twist`` connected
    and no odometry, nothing is known of the motion before the first estimate, and an
    uncorrected first image would stay in a SLAM's map (a Navtech at 8 m/s moves 2 m in a
    turn). So the first turn is held until the second one is complete; the displacement
    between their uncorrected images (:func:`bootstrap_speed`, phase correlation) gives
    the initial forward speed, and both are then imaged with it (yaw rate 0); the first
    image is emitted late, stamped at its own time (live, its latency figures count the wait
    for the second turn: one turn period more than the others'). The within-turn correction restarts
    every turn (only poses relative to t_ref are used). With ``doppler_compensation`` the
    static Doppler is removed from both ramps before they are averaged (the image of a
    Doppler radar is then the mean of the two ramps). With ``ground_range`` each cell reads
    the slant range sqrt(r^2 + h^2) of its ground range r (flat ground, radar
    ``config.height_m`` high): ground clutter lands where it is. With ``normalise =
    "beam_median"`` each beam is divided by its median power, its noise-and-clutter floor:
    a power-only radar's floor varies from beam to beam (the Navtech's does by a few dB),
    and after it 1.0 is the floor of every beam (R-SLAM's ``db_floor: 1``).

    ``threads`` (default 2) share the beams' normalisation by bands of beams and the grid's
    compiled loops by bands of rows (a pool created in ``start``, closed in ``stop``): every beam
    and cell is computed by the same code whichever thread takes it, so the images are the same
    bits with 1 thread or more.
    """

    beams = Input(RadarBeam, maxsize=8192, doc="beams of the rotating radar, in time order")
    odometer = Input(Speed, policy="sampling", history=3.0, required=False, doc="forward speed")
    gyro = Input(YawRate, policy="sampling", history=3.0, required=False, doc="yaw rate")
    twist = Input(Twist2D, policy="sampling", required=False,
                  doc="estimated velocity, used without odometer/gyro (connect with [delay] from a SLAM)")
    scan = Output(RadarScan, doc="the turn as a polar image")
    image = Output(Grid, doc="motion-corrected Cartesian image in the vehicle frame at t_ref")

    cell_m = Param(float, default=0.2, gt=0, doc="cell size of the Cartesian grid")
    range_max_m = Param(float, default=0.0, ge=0, doc="grid half extent; 0 = the radar's range_max_m")
    range_min_m = Param(float, default=0.0, ge=0, doc="cells nearer than this are blanked (vehicle body, leakage)")
    speed_mps = Param(float, default=0.0, doc="constant speed hypothesis without odometer or twist")
    yaw_rate_radps = Param(float, default=0.0, doc="constant yaw-rate hypothesis without gyro or twist")
    reference = Param(str, default="last", choices=("last", "middle"),
                      doc="t_ref of each image: the turn's last beam, or halfway between its first and last beams")
    motion_correction = Param(bool, default=True, doc="place each beam at its own pose")
    doppler_compensation = Param(bool, default=True, doc="remove the static Doppler before averaging ramps")
    ground_range = Param(bool, default=True, doc="project slant ranges onto the ground (radar config.height_m high)")
    normalise = Param(str, default="none", choices=("none", "beam_median"),
                      doc="beam_median: each beam's power divided by its median (its noise floor)")
    bootstrap = Param(bool, default=True,
                      doc="with twist connected and no odometry: the first turn waits for the second, "
                      "whose displacement gives the initial speed")
    min_turn_fraction = Param(float, default=0.5, ge=0, le=1,
                              doc="a partial last turn is imaged if it holds this fraction of a turn")
    twist_wait_s = Param(float, default=0.5, ge=0, le=5.0,
                         doc="with a fed-back twist: a complete turn waits at most this long (radar time, "
                         "beams after its last) for the twist of the previous image; 0: never waits (the turns "
                         "waiting are bounded by it: 5 s of a 4 Hz radar is 20 turns)")
    threads = Param(int, default=2, ge=1, le=4,
                    doc="threads sharing the normalisation and the grid's loops (images bit-identical whatever"
                    " the number)")

    def start(self) -> None:
        self._turn = TurnBuffer()
        self._pose: np.ndarray | None = None  # odom pose at the previous turn's last beam
        self._t_prev: int | None = None
        self.turns = 0
        self.partial_turns = 0  # imaged with fewer beams than a turn
        self.dropped_turns = 0  # a partial last turn below min_turn_fraction
        self.dropped_beams = 0  # duplicated azimuths within a turn
        self.motion_source: dict[str, int] = {}
        self._held: list[tuple[int, RadarBeam]] | None = None  # the first turn, awaiting the second
        self._held_origin: int | None = None  # the work origin of the beam that completed it (live)
        self._bootstrap_v: float | None = None
        self._t_image: int | None = None  # t_ref of the previous image
        self.stale_twist = 0  # turns imaged with a twist older than the previous image
        # complete turns waiting for the twist of the previous image: (beams, their work origin)
        self._waiting: deque[tuple[list[tuple[int, RadarBeam]], int | None]] = deque()
        # a feedback loop (the twist of a consumer of these images, through [delay]): offline its estimate of
        # the previous image is always back first, and live the builder waits for it; a twist from a
        # source beside the builder (an odometry on the same beams) is used as it comes, as offline
        self._twist_fed_back = self.twist.fed_back and not self.odometer.connected and not self.gyro.connected
        self._wait_ns = round(self.twist_wait_s * 1e9)
        # the compiled kernels (numba, from its cache) loaded now, before the first beam: at the first
        # turn they made it 0.65 s late, a live radar's first turns then dropped downstream
        self._pool = BandPool(self.threads)
        power = np.ones((4, 8), np.float32)
        for poses in (np.zeros((4, 3)), np.full((4, 3), 0.01)):  # both loops: without and with motion
            scan_to_grid(normalise_beams(power), np.linspace(0.0, 6.0, 4), poses, 1.0, 1.0, 4.0, 0.5,
                         pool=self._pool)

    def stop(self) -> None:
        pool = getattr(self, "_pool", None)
        if pool is not None:
            pool.close()

    def process(self, t: int) -> None:
        for buf in self._turn.add(t, self.beams.take()):
            self._turn_done(buf)
        if self._waiting:
            self._release(t)

    def _twist_back(self) -> bool:
        """The twist of the previous image is here (or no image yet, or none is fed back)."""
        if not self._twist_fed_back or self._t_image is None:
            return True
        last = self.twist.latest()
        return last is not None and last.timestamp >= self._t_image

    def _release(self, t: int | None) -> None:
        """Image the waiting turns whose previous twist is back, or whose wait is over at beam
        time ``t`` (``None``: the beams are exhausted, all of them), in turn order."""
        while self._waiting:
            buf, origin = self._waiting[0]
            if not (t is None or self._twist_back() or t - buf[-1][0] >= self._wait_ns):
                return
            self._waiting.popleft()
            self._flush_from(buf, origin)

    def _flush_from(self, buf: list[tuple[int, RadarBeam]], origin: int | None) -> None:
        """Image a turn that was held: the latency of its outputs counts from ``origin`` (live:
        the arrival of the beam that completed it), the wait included."""
        now = self.work_origin_ns
        self.work_origin_ns = origin
        try:
            self._flush(buf)
        finally:
            self.work_origin_ns = now

    def _turn_done(self, buf: list[tuple[int, RadarBeam]]) -> None:
        """Image a complete turn, or hold the first one for the bootstrap (see the class doc)."""
        waiting = (self.bootstrap and self.twist.connected and self.twist.get() is None
                   and not self.odometer.connected and not self.gyro.connected and self._bootstrap_v is None)
        if not waiting:
            if self._waiting or not self._twist_back():
                self._waiting.append((buf, self.work_origin_ns))
            else:
                self._flush(buf)
        elif self._held is None:
            self._held, self._held_origin = buf, self.work_origin_ns
        else:
            held, self._held = self._held, None
            self._bootstrap_v = bootstrap_speed(held, buf, self.normalise == "beam_median")
            self._flush_from(held, self._held_origin)
            self._flush(buf)

    def flush(self, t: int) -> None:
        """The beams are exhausted: image the partial last turn if it is large enough."""
        self._release(None)
        if self._held is not None:  # a single turn: no second one to bootstrap from
            held, self._held = self._held, None
            self._bootstrap_v = 0.0
            self._flush(held)
        buf = self._turn.take()
        if not buf:
            return
        if len(buf) >= self.min_turn_fraction * buf[0][1].config.beams_per_turn and len(buf) >= 2:
            self._flush(buf)
        else:
            self.dropped_turns += 1

    def _rates(self, t_ns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Speed and yaw rate at ``t_ns`` from the sensor histories, the estimated twist or
        the constants (see the class doc)."""
        twist = self.twist.get()
        out, sources = [], []
        for port, attr, twist_attr, const in ((self.odometer, "speed_mps", "speed_mps", self.speed_mps),
                                              (self.gyro, "yaw_rate_radps", "yaw_rate_radps", self.yaw_rate_radps)):
            hist = port.between(int(t_ns[0]) - 500_000_000, int(t_ns[-1]) + 500_000_000)
            if hist:
                ts = np.array([s.timestamp for s in hist], np.int64)
                vs = np.array([getattr(s.data, attr) for s in hist], float)
                out.append(np.interp(t_ns.astype(float), ts.astype(float), vs))
                sources.append(port.name)
            elif twist is not None:
                out.append(np.full(len(t_ns), float(getattr(twist, twist_attr))))
                sources.append("twist")
            elif self._bootstrap_v is not None:
                out.append(np.full(len(t_ns), self._bootstrap_v if attr == "speed_mps" else 0.0))
                sources.append("bootstrap")
            else:
                out.append(np.full(len(t_ns), const))
                sources.append("constant")
        if (self.twist.connected and self._t_image is not None and self.odometer.name not in sources
                and self.gyro.name not in sources):  # the motion comes from the fed-back estimate, if any
            last = self.twist.latest()
            if last is None or last.timestamp < self._t_image:
                self.stale_twist += 1  # the estimate of the previous turn was not back (live), or none came
        key = "+".join(dict.fromkeys(sources))
        self.motion_source[key] = self.motion_source.get(key, 0) + 1
        return out[0], out[1]

    def _flush(self, buf: list[tuple[int, RadarBeam]]) -> None:
        t_ns = np.array([t for t, _ in buf], np.int64)
        first = buf[0][1]
        config = first.config
        azimuth = np.array([b.azimuth_rad for _, b in buf])
        up = np.array([b.up for _, b in buf], np.float32)  # np.stack's rows, in a seventh of its time
        down = np.array([b.down for _, b in buf], np.float32)
        # dead reckoning from the previous turn's last beam through every beam of this turn
        grid_t = t_ns if self._t_prev is None or self._t_prev >= t_ns[0] else np.concatenate([[self._t_prev], t_ns])
        v, w = self._rates(grid_t)
        start = (0.0, 0.0, 0.0) if self._pose is None else tuple(self._pose)
        odom = integrate_poses(grid_t, v, w, start)[-len(t_ns):]
        if self.reference == "last":
            t_ref, ref = int(t_ns[-1]), odom[-1]
        else:  # halfway between the first and the last beam (Oxford's ground-truth time)
            t_ref = int(t_ns[0] + (t_ns[-1] - t_ns[0]) // 2)
            rel_t = (t_ns - t_ns[0]).astype(float)
            ref = np.array([np.interp(float(t_ref - t_ns[0]), rel_t, odom[:, k]) for k in range(3)])
        self._pose, self._t_prev, self._t_image = odom[-1], int(t_ns[-1]), t_ref
        rel = relative_to(odom, ref) if self.motion_correction else np.zeros((len(t_ns), 3))
        if self.doppler_compensation and down.size:
            power = doppler_compensated_power(up, down, azimuth, float(np.mean(v[-len(t_ns):])), config)
        else:
            power = up
        if self.normalise == "beam_median":
            power = normalise_beams(power, self._pool)
        range_max = self.range_max_m or config.range_max_m
        height = config.height_m if self.ground_range else 0.0
        table = AzimuthTable(azimuth)
        self.dropped_beams += table.dropped
        data, (ox, oy) = scan_to_grid(power, azimuth, rel, config.range_per_bin_m, self.cell_m, range_max, height,
                                      config.range_offset_m, self.range_min_m, pool=self._pool)
        self.scan.emit(t_ref, RadarScan(first.turn, t_ns, azimuth, up, down, config))
        has_odometry = self.odometer.latest() is not None or self.gyro.latest() is not None
        pose = Pose2D(float(ref[0]), float(ref[1]), wrap_angle(float(ref[2])), frame="odom") if has_odometry else None
        self.image.emit(t_ref, Grid(data, self.cell_m, ox, oy, "vehicle", pose))
        self.turns += 1
        self.partial_turns += table.n < config.beams_per_turn

    def summary(self) -> dict:
        out = {"turns": self.turns, "motion": dict(self.motion_source)}
        for k in ("partial_turns", "dropped_turns", "dropped_beams", "stale_twist"):
            if getattr(self, k, 0):
                out[k] = getattr(self, k)
        return out
