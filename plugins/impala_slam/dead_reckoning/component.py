"""``slam.DeadReckoning``: the component (ports, parameters, sample handling). The algorithm, and
what it follows, is described in :mod:`impala_slam.dead_reckoning.core`.
"""

from __future__ import annotations

import math

from impala_flow import Component, Input, Output, Param, Periodic
from impala_flow.msgs import Pose2D
from impala_msgs import Speed, YawRate

from .core import arc_step

__all__ = ["DeadReckoning"]


class DeadReckoning(Component):
    """Integrates odometer speed and gyro yaw rate into a pose (frame ``odom``) emitted every
    ``period_s``; starts at (x0_m, y0_m, theta0_rad) at the first sample."""

    odometer = Input(Speed, doc="forward speed")
    gyro = Input(YawRate, doc="yaw rate, counter-clockwise positive")
    pose = Output(Pose2D, doc="dead-reckoned pose")
    tick = Periodic("period_s")

    period_s = Param(float, default=0.1, gt=0, doc="output period (s)")
    x0_m = Param(float, default=0.0)
    y0_m = Param(float, default=0.0)
    theta0_rad = Param(float, default=0.0)
    frame = Param(str, default="odom", doc="frame of the output poses")

    def start(self) -> None:
        self.state = (self.x0_m, self.y0_m, self.theta0_rad)
        self.t_state: int | None = None
        self.v_mps: float | None = None
        self.w_radps: float | None = None

    def _advance(self, t_ns: int, v_new: float | None, w_new: float | None) -> None:
        """Move the state to ``t_ns`` where one sensor reads a new value (midpoint rates)."""
        if self.t_state is not None and self.v_mps is not None and self.w_radps is not None:
            v_mid = 0.5 * (self.v_mps + (self.v_mps if v_new is None else v_new))
            w_mid = 0.5 * (self.w_radps + (self.w_radps if w_new is None else w_new))
            self.state = arc_step(*self.state, v_mid, w_mid, (t_ns - self.t_state) * 1e-9)
        self.t_state = t_ns
        if v_new is not None:
            self.v_mps = v_new
        if w_new is not None:
            self.w_radps = w_new

    def process(self, t: int) -> None:
        if self.trigger == "odometer":
            s = self.odometer.take_sample()
            self._advance(s.timestamp, float(s.data.speed_mps), None)
        elif self.trigger == "gyro":
            s = self.gyro.take_sample()
            self._advance(s.timestamp, None, float(s.data.yaw_rate_radps))
        elif self.t_state is not None and self.v_mps is not None and self.w_radps is not None:
            # tick: extrapolate the held rates up to t without committing
            x, y, th = arc_step(*self.state, self.v_mps, self.w_radps, (t - self.t_state) * 1e-9)
            self.pose.emit(t, Pose2D(x, y, (th + math.pi) % (2 * math.pi) - math.pi, frame=self.frame))
