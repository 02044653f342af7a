"""Clocks: replay pacing (speed factor or 'max'), the live mission clock, a fake clock.

Pacing only sleeps: it never changes the order in which events are processed, so a run
at ``speed: max`` and a run at ``speed: 1.0`` produce bit-identical outputs.
"""

from __future__ import annotations

import time

__all__ = ["ReplayClock", "MissionClock", "FakeClock", "parse_speed"]


def parse_speed(value: object) -> float | None:
    """``'max'`` (or None) -> None; a positive number -> float. Anything else: ValueError."""
    if value is None or value == "max":
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise ValueError(f"speed must be a positive number or 'max', got {value!r}")
    try:
        v = float(value)
    except ValueError:
        raise ValueError(f"speed must be a positive number or 'max', got {value!r}") from None
    if not v > 0:
        raise ValueError(f"speed must be a positive number or 'max', got {value!r}")
    return v


class ReplayClock:
    """Paces an offline run: mission time advances ``speed`` times faster than wall time."""

    def __init__(self, speed: float | None = None) -> None:
        self.speed = speed
        self._t0: int | None = None
        self._wall0 = 0
        self.slept_s = 0.0

    def wait_until(self, t_ns: int) -> None:
        if self.speed is None:
            return
        if self._t0 is None:
            self._t0, self._wall0 = t_ns, time.perf_counter_ns()
            return
        due = self._wall0 + (t_ns - self._t0) / self.speed
        ahead_s = (due - time.perf_counter_ns()) / 1e9
        if ahead_s > 0.0005:
            time.sleep(ahead_s)
            self.slept_s += ahead_s


class FakeClock(ReplayClock):
    """A replay clock that records what it would have slept instead of sleeping."""

    def __init__(self, speed: float | None = 1.0) -> None:
        super().__init__(speed)
        self.waits: list[int] = []

    def wait_until(self, t_ns: int) -> None:
        self.waits.append(t_ns)


class MissionClock:
    """The live mission clock: the monotonic clock mapped to mission time (int ns).

    ``epoch_ns`` is the mission time at ``start()``; it defaults to the wall-clock time
    (UNIX epoch ns) so live recordings carry absolute times.
    """

    def __init__(self, epoch_ns: int | None = None) -> None:
        self.epoch_ns = time.time_ns() if epoch_ns is None else epoch_ns
        self._mono0 = time.monotonic_ns()

    def now_ns(self) -> int:
        return self.epoch_ns + (time.monotonic_ns() - self._mono0)
