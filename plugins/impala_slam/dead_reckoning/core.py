"""Dead reckoning from odometer and gyro alone: the baseline every R-SLAM report shows.

Between two consecutive sensor samples (of either sensor) the speed and the yaw rate are
taken at the interval's midpoint (mean of the values at its ends, the other sensor's value
held) and the pose advanced along the exact circular arc of that constant (v, w): second
order in the sample interval, exact for piecewise-constant rates.
"""

from __future__ import annotations

import math

__all__ = ["arc_step"]


def arc_step(x: float, y: float, th: float, v_mps: float, w_radps: float, dt_s: float) -> tuple[float, float, float]:
    """Pose after ``dt_s`` at constant speed ``v`` and yaw rate ``w`` (exact arc)."""
    dth = w_radps * dt_s
    # chord length v dt sinc(dth/2), along the mean heading th + dth/2
    half = 0.5 * dth
    sinc = 1.0 - half * half / 6.0 if abs(half) < 1e-4 else math.sin(half) / half
    ds = v_mps * dt_s * sinc
    return x + ds * math.cos(th + half), y + ds * math.sin(th + half), th + dth
