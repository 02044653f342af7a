"""``radar.PanoramicBuilder``: one turn of beams -> RadarScan + motion-corrected Grid."""

from __future__ import annotations

import numpy as np

from impala_flow.component import Component, Input, Output, Param
from impala_flow.msgs import Grid, Pose2D, RadarBeam, RadarScan, Speed, YawRate, wrap_angle

from .panoramic import doppler_compensated_power, integrate_poses, relative_to, scan_to_grid
from .turns import TurnBuffer

__all__ = ["PanoramicBuilder"]


class PanoramicBuilder(Component):
    """Collects one antenna turn into a polar image (``scan``) and a Cartesian grid
    (``image``) of ``cell_m`` cells over the radar range, each beam placed at the vehicle
    pose of its own time (seed 1 §4.1.1; see :mod:`impala_radar.frontend.panoramic`).

    Grid contract: stamped with the turn's reference time t_ref = its last beam's time;
    ``data`` float32 intensity (power, bilinear from the polar image; 0 where not
    observed), row = y, column = x, in the vehicle frame at t_ref (x forward, y left), the
    radar at the centre cell; ``origin_x_m``/``origin_y_m`` the centre of cell (0, 0)
    (= -half extent); ``frame = "vehicle"``; ``pose`` the dead-reckoned pose (frame
    ``odom``) at t_ref, integrated continuously across turns.

    Motion during the turn comes from the ``odometer`` and ``gyro`` histories when they are
    connected and hold samples over the turn, otherwise from the constant ``speed_mps`` /
    ``yaw_rate_radps`` hypothesis (a power-only radar replayed without odometry). The
    within-turn correction restarts every turn (only poses relative to t_ref are used).
    With ``doppler_compensation`` the static Doppler is removed from both ramps before they
    are averaged (the image of a Doppler radar is then the mean of the two ramps). With
    ``ground_range`` each cell reads the slant range sqrt(r^2 + h^2) of its ground range r
    (flat ground, radar ``config.height_m`` high): ground clutter lands where it is.
    """

    beams = Input(RadarBeam, maxsize=8192, doc="beams of the rotating radar, in time order")
    odometer = Input(Speed, policy="sampling", history=3.0, required=False, doc="forward speed")
    gyro = Input(YawRate, policy="sampling", history=3.0, required=False, doc="yaw rate")
    scan = Output(RadarScan, doc="the turn as a polar image")
    image = Output(Grid, doc="motion-corrected Cartesian image in the vehicle frame at t_ref")

    cell_m = Param(float, default=0.2, gt=0, doc="cell size of the Cartesian grid")
    range_max_m = Param(float, default=0.0, ge=0, doc="grid half extent; 0 = the radar's range_max_m")
    speed_mps = Param(float, default=0.0, doc="constant speed hypothesis without odometer")
    yaw_rate_radps = Param(float, default=0.0, doc="constant yaw-rate hypothesis without gyro")
    motion_correction = Param(bool, default=True, doc="place each beam at its own pose")
    doppler_compensation = Param(bool, default=True, doc="remove the static Doppler before averaging ramps")
    ground_range = Param(bool, default=True, doc="project slant ranges onto the ground (radar config.height_m high)")

    def start(self) -> None:
        self._turn = TurnBuffer()
        self._pose: np.ndarray | None = None  # odom pose at the previous t_ref
        self._t_prev: int | None = None
        self.turns = 0

    def process(self, t: int) -> None:
        for buf in self._turn.add(t, self.beams.take()):
            self._flush(buf)

    def _rates(self, t_ns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Speed and yaw rate at ``t_ns`` from the sensor histories, or the constants."""
        out = []
        for port, attr, const in ((self.odometer, "speed_mps", self.speed_mps),
                                  (self.gyro, "yaw_rate_radps", self.yaw_rate_radps)):
            hist = port.between(int(t_ns[0]) - 500_000_000, int(t_ns[-1]) + 500_000_000)
            if hist:
                ts = np.array([s.timestamp for s in hist], np.int64)
                vs = np.array([getattr(s.data, attr) for s in hist], float)
                out.append(np.interp(t_ns.astype(float), ts.astype(float), vs))
            else:
                out.append(np.full(len(t_ns), const))
        return out[0], out[1]

    def _flush(self, buf: list[tuple[int, RadarBeam]]) -> None:
        t_ns = np.array([t for t, _ in buf], np.int64)
        first = buf[0][1]
        config = first.config
        azimuth = np.array([b.azimuth_rad for _, b in buf])
        up = np.stack([b.up for _, b in buf]).astype(np.float32)
        down = np.stack([b.down for _, b in buf]).astype(np.float32)
        # dead reckoning from the previous reference time through every beam of this turn
        grid_t = t_ns if self._t_prev is None or self._t_prev >= t_ns[0] else np.concatenate([[self._t_prev], t_ns])
        v, w = self._rates(grid_t)
        start = (0.0, 0.0, 0.0) if self._pose is None else tuple(self._pose)
        odom = integrate_poses(grid_t, v, w, start)[-len(t_ns):]
        ref = odom[-1]
        self._pose, self._t_prev = ref, int(t_ns[-1])
        if self.motion_correction:
            rel = relative_to(odom, ref)
        else:
            rel = np.zeros((len(t_ns), 3))
        if self.doppler_compensation and down.size:
            power = doppler_compensated_power(up, down, azimuth, float(np.mean(v[-len(t_ns):])), config)
        else:
            power = up
        range_max = self.range_max_m or config.range_max_m
        height = config.height_m if self.ground_range else 0.0
        data, (ox, oy) = scan_to_grid(power, azimuth, rel, config.range_per_bin_m, self.cell_m, range_max, height)
        t_ref = int(t_ns[-1])
        self.scan.emit(t_ref, RadarScan(first.turn, t_ns, azimuth, up, down, config))
        pose = Pose2D(float(ref[0]), float(ref[1]), wrap_angle(float(ref[2])), frame="odom")
        self.image.emit(t_ref, Grid(data, self.cell_m, ox, oy, "vehicle", pose))
        self.turns += 1

    def summary(self) -> dict:
        return {"turns": self.turns}
