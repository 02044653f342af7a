"""Small components shared by the engine tests."""

from __future__ import annotations

import numpy as np

from impala_flow import Component, Input, Output, Param, Source


class Counter(Source):
    """Emits 0..n-1 every period_ns on 'out'."""

    out = Output(float)
    n = Param(int, default=10, ge=0)
    period_ns = Param(int, default=1_000_000, ge=1)
    t0_ns = Param(int, default=0)

    def generate(self):
        for i in range(self.n):
            yield self.t0_ns + i * self.period_ns, "out", float(i)

    def duration_hint_ns(self):
        return self.n * self.period_ns


class Scale(Component):
    x = Input(float)
    y = Output(float)
    gain = Param(float, default=2.0, ge=0.0, doc="multiplier")

    def process(self, t):
        self.y.emit(t, self.x.take() * self.gain)


class Boom(Component):
    """Raises on the sample whose value is `at`."""

    x = Input(float)
    y = Output(float)
    at = Param(float, default=3.0)

    def start(self):
        self.stopped = False

    def process(self, t):
        v = self.x.take()
        if v == self.at:
            raise ValueError(f"bad value {v}")
        self.y.emit(t, v)

    def stop(self):
        self.stopped = True


class ArraySource(Source):
    out = Output(np.ndarray)
    n = Param(int, default=5)
    size = Param(int, default=16)
    seed = Param(int, default=0)

    def generate(self):
        rng = np.random.default_rng(self.seed)
        for i in range(self.n):
            yield i * 100_000_000, "out", rng.standard_normal(self.size)


