"""ClockSync: a sensor's device clock mapped to mission time, robust to network delay.

A live sensor stamps each sample with its own clock (``device_ns``); the host receives it
later, at ``host_ns`` on the mission clock. The model (one-way, as in TICSync's one-way
case, Harrison & Newman, "TICSync: Knowing When Things Happened", ICRA 2011)::

    host_ns = device_ns + offset + drift * (device_ns - x_c) + delay,    delay >= 0, random

so every observation ``(x, y) = (device_ns, host_ns - device_ns)`` lies on or above the line
``offset + drift * (x - x_c)``. The estimate is the minimum-delay line: the line under every
observation that is highest at the window's centre ``x_c`` (the linear programme of Moon,
Skelly & Towsley 1999, which TICSync's one-way estimator solves on the lower convex hull):
its slope is the slope of the lower hull's edge over ``x_c`` (clamped to ``max_drift_ppm``,
and held at its last value until the window spans ``drift_min_span_s``), its offset the
highest value under every hull vertex. One-way messages cannot tell a constant transport
latency from the offset: the minimum delay is part of ``offset`` (mission time is the time
the fastest sample would have reached the host).

Bounded: the window keeps, per ``window_s / buckets`` of device time, only the lowest
observation (the lower hull of the bucket minima equals the hull of all points up to
``drift * bucket width``, 31 us at 100 ppm and the defaults), so memory is ``buckets``
entries (:attr:`ClockSync.window_bytes`) whatever the sample rate, and the hull (Andrew's
monotone chain over at most ``buckets`` points) is recomputed only when a bucket minimum
changes or the window slides.

Smooth: the mapping given out is a line anchored at the last output; each update moves it
towards the estimate by at most ``slew`` times the device time elapsed and ``max_slew_ns``,
so consecutive mapped stamps keep the device's spacing to within those bounds and never go
back (for increasing device stamps; an output held back to stay monotonic is counted).

Steps: an observation more than ``step_threshold_ns`` below the line (delay cannot be
negative: the device clock jumped forward) or a device stamp more than the threshold behind
the previous one (the device clock went back) is a step, at once; ``confirm_count``
observations in a row more than the threshold above the line (a delay that long, or the
device clock went back by less than the spacing of its samples) are a backward step. A step
is counted, logged, kept in :meth:`ClockSync.summary` (the last ``16``), and the estimate
restarts from the observations after it, keeping the drift (a step does not change the rate).
"""

from __future__ import annotations

import logging
import statistics
import sys
from array import array
from collections import deque
from typing import Any

__all__ = ["ClockSync"]

log = logging.getLogger("impala_flow.clocksync")

#: the last steps kept in the summary
_STEPS_KEPT = 16


def _lower_hull(points: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """Andrew's monotone chain, lower half: ``points`` sorted by x (ties: any order)."""
    hull: list[tuple[int, int]] = []
    for p in points:
        while len(hull) >= 2:
            (x1, y1), (x2, y2) = hull[-2], hull[-1]
            # drop hull[-1] unless hull[-2] -> hull[-1] -> p turns left (strictly convex from below)
            if (x2 - x1) * (p[1] - y1) - (y2 - y1) * (p[0] - x1) <= 0:
                hull.pop()
            else:
                break
        if hull and hull[-1][0] == p[0]:      # same x: keep the lower point
            if p[1] < hull[-1][1]:
                hull[-1] = p
            continue
        hull.append(p)
    return hull


class ClockSync:
    """Maps a device clock to mission time from ``(device_ns, host_ns)`` observations.

    ``update(device_ns, host_ns)`` adds one observation and returns the device stamp mapped to
    mission time (int ns); ``to_mission_ns(device_ns)`` maps without observing; ``summary()``
    gives offset, drift, steps and residuals. See the module docstring for the method.

    Args:
        window_s: device time the estimate looks back over (the drift is fitted over it).
        step_threshold_ns: a jump of the device clock larger than this is a step.
        buckets: the window's resolution: one kept observation per ``window_s / buckets``.
        slew: the largest correction per ns of device time elapsed (0.01: 10 us per ms).
        max_slew_ns: the largest correction of one update, whatever the time elapsed.
        max_drift_ppm: the drift estimate is clamped to +-this.
        drift_min_span_s: the drift is fitted once the window spans this much device time.
        confirm_count: observations in a row above the line by more than the threshold that
            make a backward step.
        residuals_kept: the last residuals kept for the median in the summary.
    """

    def __init__(self, window_s: float = 20.0, step_threshold_ns: int = 50_000_000, *, buckets: int = 64,
                 slew: float = 0.01, max_slew_ns: int = 500_000, max_drift_ppm: float = 500.0,
                 drift_min_span_s: float = 2.0, confirm_count: int = 8, residuals_kept: int = 4096) -> None:
        checks = [("window_s", window_s > 0), ("step_threshold_ns", step_threshold_ns > 0),
                  ("buckets", buckets >= 2), ("slew", 0 < slew < 1), ("max_slew_ns", max_slew_ns > 0),
                  ("max_drift_ppm", 0 <= max_drift_ppm < 1e5), ("drift_min_span_s", drift_min_span_s >= 0),
                  ("confirm_count", confirm_count >= 1), ("residuals_kept", residuals_kept >= 1)]
        for name, ok in checks:
            if not ok:
                raise ValueError(f"ClockSync: {name}={locals()[name]!r} is out of range")
        self.window_ns = int(window_s * 1e9)
        self.step_threshold_ns = int(step_threshold_ns)
        self.buckets = int(buckets)
        self.bucket_ns = max(1, self.window_ns // self.buckets)
        self.slew = float(slew)
        self.max_slew_ns = int(max_slew_ns)
        self.max_drift = max_drift_ppm * 1e-6
        self.drift_min_span_ns = int(drift_min_span_s * 1e9)
        self.confirm_count = int(confirm_count)
        self.residuals_kept = int(residuals_kept)
        self.steps: list[dict[str, int]] = []
        self.step_count = 0
        self.observations = 0
        self.held = 0
        self._drift = 0.0
        self.reset()

    # -- state ---------------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget everything: the next observation starts a new estimate (counters are zeroed)."""
        self._restart()
        self._drift = 0.0
        self._last_dev: int | None = None
        self._last_out = 0
        self.steps, self.step_count, self.observations, self.held = [], 0, 0, 0
        self._residuals = array("q")
        self._res_pos = 0
        self._max_residual = 0

    def _restart(self) -> None:
        """Empty the window (after a step, or on reset); the drift and the output anchor stay."""
        self._window: deque[list[int]] = deque()   # [bucket index, x, y], increasing index
        self._epoch: int | None = None
        self._offset_c = 0          # the line's value at _xc
        self._xc = 0
        self._pending: list[tuple[int, int]] = []

    @property
    def drift_ppm(self) -> float:
        """The estimated drift of mission time against device time, in ppm."""
        return self._drift * 1e6

    @property
    def offset_ns(self) -> int:
        """mission - device at the last mapped device stamp (the mapping given out)."""
        return 0 if self._last_dev is None else self._last_out - self._last_dev

    @property
    def window_bytes(self) -> int:
        """The memory held by the window and the residuals (bounded by ``buckets`` and ``residuals_kept``)."""
        per_bucket = sys.getsizeof([0, 0, 0]) + 3 * sys.getsizeof(2**62)
        return (sys.getsizeof(self._window) + len(self._window) * per_bucket
                + self._residuals.itemsize * len(self._residuals)
                + len(self._pending) * (sys.getsizeof((0, 0)) + 2 * sys.getsizeof(2**62)))

    def _line(self, x: int) -> int:
        """The estimate's host - device at device time ``x``."""
        return self._offset_c + round(self._drift * (x - self._xc))

    def to_mission_ns(self, device_ns: int) -> int:
        """The device stamp mapped to mission time with the mapping given out so far."""
        if self._last_dev is None:
            raise ValueError("ClockSync.to_mission_ns: no observation yet (call update first)")
        return self._last_out + (device_ns - self._last_dev) + round(self._drift * (device_ns - self._last_dev))

    # -- observations ----------------------------------------------------------------------------

    def update(self, device_ns: int, host_ns: int) -> int:
        """Add one observation (device stamp, host receive time on the mission clock); return the
        device stamp mapped to mission time."""
        device_ns, host_ns = int(device_ns), int(host_ns)
        self.observations += 1
        y = host_ns - device_ns
        if self._last_dev is None:
            self._add(device_ns, y)
            self._last_dev, self._last_out = device_ns, host_ns
            return host_ns
        if device_ns < self._last_dev - self.step_threshold_ns:
            return self._step(device_ns, host_ns, [(device_ns, y)], "backward")
        residual = y - self._line(device_ns)
        settled = self.observations > self.confirm_count
        if residual < -self.step_threshold_ns and settled:
            return self._step(device_ns, host_ns, [(device_ns, y)], "forward")
        if residual > self.step_threshold_ns and settled:
            self._pending.append((device_ns, y))
            if len(self._pending) >= self.confirm_count:
                return self._step(device_ns, host_ns, self._pending, "backward")
            return self._emit(device_ns, self.to_mission_ns(device_ns))
        self._pending.clear()
        self._record_residual(residual)
        self._add(device_ns, y)
        predicted = self.to_mission_ns(device_ns)
        target = device_ns + self._line(device_ns)
        elapsed = max(0, device_ns - self._last_dev)
        limit = min(self.max_slew_ns, int(self.slew * elapsed))
        return self._emit(device_ns, predicted + max(-limit, min(limit, target - predicted)))

    def _emit(self, device_ns: int, out: int) -> int:
        if device_ns < self._last_dev:      # an out-of-order stamp: mapped, the anchor stays
            return out
        if out < self._last_out:
            self.held += 1
            out = self._last_out
        self._last_dev, self._last_out = device_ns, out
        return out

    def _record_residual(self, residual: int) -> None:
        if len(self._residuals) < self.residuals_kept:
            self._residuals.append(residual)
        else:
            self._residuals[self._res_pos] = residual
            self._res_pos = (self._res_pos + 1) % self.residuals_kept
        self._max_residual = max(self._max_residual, abs(residual))

    def _step(self, device_ns: int, host_ns: int, points: list[tuple[int, int]], direction: str) -> int:
        """A device clock step: restart the window from ``points``, jump to the new line."""
        size_ns = -min(y - self._line(x) for x, y in points)   # the device clock's jump, + = forward
        self.step_count += 1
        self.steps = ([*self.steps, {"device_ns": device_ns, "host_ns": host_ns, "size_ns": size_ns}]
                      [-_STEPS_KEPT:])
        log.warning("device clock stepped %s by about %.1f ms at device t=%d ns (step %d): re-estimating",
                    direction, abs(size_ns) / 1e6, device_ns, self.step_count)
        kept = list(points)
        self._restart()
        for x, y in kept:
            self._add(x, y)
        out = device_ns + self._line(device_ns)
        if out < self._last_out:
            self.held += 1
            out = self._last_out
        self._last_dev, self._last_out = device_ns, out
        return out

    def _add(self, x: int, y: int) -> None:
        """Put one observation in the window; re-estimate when the lower envelope changed."""
        if self._epoch is None:
            self._epoch = x
        idx = (x - self._epoch) // self.bucket_ns
        window = self._window
        changed = False
        if not window or idx > window[-1][0]:
            window.append([idx, x, y])
            changed = True
            while window[0][0] <= idx - self.buckets:
                window.popleft()
        else:                                   # the newest bucket, or an out-of-order stamp's
            pos = len(window) - 1
            while pos > 0 and window[pos][0] > idx:
                pos -= 1
            entry = window[pos]
            if entry[0] == idx:
                if y < entry[2]:
                    entry[1], entry[2] = x, y
                    changed = True
            elif idx > window[-1][0] - self.buckets:
                window.insert(pos + (entry[0] < idx), [idx, x, y])
                changed = True
        if changed:
            self._estimate()

    def _estimate(self) -> None:
        """The minimum-delay line: highest at the window centre, under every kept observation."""
        points = sorted((e[1], e[2]) for e in self._window)
        hull = _lower_hull(points)
        x0, x1 = points[0][0], points[-1][0]
        xc = x0 + (x1 - x0) // 2
        drift = self._drift
        if x1 - x0 >= max(1, self.drift_min_span_ns) and len(hull) >= 2:
            for (xa, ya), (xb, yb) in zip(hull, hull[1:], strict=False):
                if xa <= xc <= xb:
                    drift = (yb - ya) / (xb - xa)
                    break
            drift = max(-self.max_drift, min(self.max_drift, drift))
        self._drift = drift
        self._xc = xc
        self._offset_c = min(y - round(drift * (x - xc)) for x, y in hull)

    def summary(self) -> dict[str, Any]:
        """offset_ns, drift_ppm, steps, observations, residuals (max, median: delay above the minimum)."""
        return {
            "offset_ns": self.offset_ns,
            "drift_ppm": round(self.drift_ppm, 3),
            "steps": self.step_count,
            "step_events": list(self.steps),
            "observations": self.observations,
            "held": self.held,
            "max_residual_ns": self._max_residual,
            "median_residual_ns": int(statistics.median(self._residuals)) if self._residuals else 0,
            "window_points": len(self._window),
            "window_bytes": self.window_bytes,
        }
