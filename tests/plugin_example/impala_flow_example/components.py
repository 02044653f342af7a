"""The example plugin's components.

``Counter`` is a source (it yields samples), ``MovingAverage`` and ``Threshold`` are
processing components, ``CsvWriter`` is a sink that writes what it receives to a file.
Ports and parameters are declared on the class; the engine checks a YAML graph against
these declarations before anything runs.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator
from numbers import Real
from pathlib import Path
from typing import Any, TextIO

from impala_flow import Component, Input, Output, Param, Source

__all__ = ["Counter", "MovingAverage", "Threshold", "CsvWriter"]


class Counter(Source):
    """An integer counter at a fixed rate: first, first + step, ... (count samples).

    Sample ``k`` is stamped ``t0_ns + round(k * 1e9 / rate)`` (int nanoseconds).
    """

    value = Output(int, doc="the counter")
    rate = Param(float, default=10.0, gt=0, doc="samples per second of mission time")
    count = Param(int, default=10, ge=0, doc="number of samples produced")
    first = Param(int, default=0, doc="first value")
    step = Param(int, default=1, doc="increment between two samples")
    t0_ns = Param(int, default=0, ge=0, doc="timestamp of the first sample, ns")

    def generate(self) -> Iterator[tuple[int, str, Any]]:
        for k in range(self.count):
            yield self.t0_ns + round(k * 1e9 / self.rate), "value", self.first + k * self.step

    def duration_hint_ns(self) -> int | None:
        return round((self.count - 1) * 1e9 / self.rate) if self.count > 1 else None


class MovingAverage(Component):
    """Mean of the last samples of x (window of them), emitted at each sample's time.

    Until ``window`` samples have arrived, the mean of those received so far.
    """

    x = Input(Real, doc="numbers to average (each sample triggers)")
    mean = Output(float, doc="moving average of x")
    window = Param(int, default=4, ge=1, doc="number of samples averaged")

    def start(self) -> None:
        self._buf: deque[float] = deque(maxlen=self.window)

    def process(self, t: int) -> None:
        self._buf.append(float(self.x.take()))
        self.mean.emit(t, math.fsum(self._buf) / len(self._buf))


class Threshold(Component):
    """Tells, for every sample of x, whether it is above the current threshold.

    The threshold is the last value received on ``level`` (a sampling input: it never
    triggers), or the ``level`` parameter until a first value arrives or when ``level``
    is not connected. ``crossings`` in the run summary counts the changes of state.
    """

    x = Input(Real, doc="values compared with the threshold (each sample triggers)")
    level = Input(Real, policy="sampling", required=False, doc="threshold, last value wins")
    above = Output(bool, doc="x > threshold")
    default_level = Param(float, default=0.0, doc="threshold before any sample on 'level'")

    def start(self) -> None:
        self._state: bool | None = None
        self._crossings = 0

    def process(self, t: int) -> None:
        x = self.x.take()
        above = bool(x > self.level.get(self.default_level))
        if self._state is not None and above != self._state:
            self._crossings += 1
        self._state = above
        self.above.emit(t, above)

    def summary(self) -> dict[str, Any]:
        return {"crossings": self._crossings}


class CsvWriter(Component):
    """Writes every sample it receives as a line 't_ns,value' of a CSV file.

    The value is written with ``repr``, so floats read back exactly.
    """

    x = Input(object, doc="samples to write")
    path = Param(str, doc="CSV file written (parent folders are created)")
    _file: TextIO | None = None
    _rows = 0

    def start(self) -> None:
        out = Path(self.path)
        out.parent.mkdir(parents=True, exist_ok=True)
        self._file = out.open("w", encoding="utf-8", newline="")
        self._file.write("t_ns,value\n")

    def process(self, t: int) -> None:
        s = self.x.take_sample()
        if self._file is not None:
            self._file.write(f"{s.timestamp},{s.data!r}\n")
        self._rows += 1

    def stop(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    def summary(self) -> dict[str, Any]:
        return {"rows": self._rows}
