"""Dead reckoning from odometer and gyro alone: the baseline every R-SLAM report shows.

Between two consecutive sensor samples (of either sensor) the speed and the yaw rate are
taken at the interval's midpoint (mean of the values at its ends, the other sensor's value
held) and the pose advanced along the exact circular arc of that constant (v, w): second
order in the sample interval, exact for piecewise-constant rates.
"""

from __future__ import annotations

import math

from impala_flow import Component, Input, Output, Param, Periodic
from impala_flow.msgs import Pose2D
from impala_msgs import Speed, YawRate

__all__ = ["DeadReckoning", "arc_step"]


def arc_step(x: float, y: float, th: float, v_mps: float, w_radps: float, dt_s: float) -> tuple[float, float, float]:
    """Pose after ``dt_s`` at constant speed ``v`` and yaw rate ``w`` (exact arc)."""
    dth = w_radps * dt_s
    # chord length v dt sinc(dth/2), along the mean heading th + dth/2
    half = 0.5 * dth
    sinc = 1.0 - half * half / 6.0 if abs(half) < 1e-4 else math.sin(half) / half
    ds = v_mps * dt_s * sinc
    return x + ds * math.cos(th + half), y + ds * math.sin(th + half), th + dth


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
