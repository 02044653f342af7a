"""A small plugin for the command-line tests, installed per test through a ``.dist-info``
folder on the path (entry point ``clitest``), so a subprocess sees it too.

Besides a few toy components it mimics the shape of the radar chain (8 components,
fan-out, a delayed feedback) for the graph pictures.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from impala_flow import Component, Input, Output, Param, Source
from impala_flow.msgs import Grid, Points2D, Pose2D
from impala_flow.plugins import hookimpl
from impala_msgs import ObjectStates, RadarBeam, Speed, YawRate


class Ticker(Source):
    """Emit 0.0, 1.0, 2.0, ... every period.

    Second paragraph, not shown in listings.
    """

    tick = Output(float, doc="the count, as a float")
    count = Param(int, default=5, ge=1, le=1_000_000, doc="number of samples")
    period = Param(float, default=0.1, gt=0, doc="seconds between samples")

    def generate(self) -> Iterator[tuple[int, str, Any]]:
        step = int(round(self.period * 1e9))
        for i in range(self.count):
            yield i * step, "tick", float(i)


class Gain(Component):
    """Multiply every number by a gain."""

    x = Input(float, doc="numbers in")
    bias = Input(float, policy="sampling", required=False, doc="added to every output")
    y = Output(float)
    gain = Param(float, default=2.0, ge=0, lt=100, doc="multiplier")
    mode = Param(str, default="linear", choices=("linear", "square"), doc="how x is used")

    def process(self, t: int) -> None:
        x = self.x.take()
        self.y.emit(t, (x if self.mode == "linear" else x * x) * self.gain + self.bias.get(0.0))


class Boom(Component):
    """Raise on the n-th sample (to test error reporting)."""

    x = Input(float)
    at = Param(int, default=2, ge=0, doc="index of the sample that raises")

    def start(self) -> None:
        self.n = 0

    def process(self, t: int) -> None:
        self.x.take()
        if self.n == self.at:
            raise ValueError("boom on purpose")
        self.n += 1


class Printer(Component):
    """Print every sample with a label."""

    x = Input(float)
    label = Param(str, doc="printed before each value")
    gains = Param(list, default=[1.0], ge=0, doc="one gain per line")

    def process(self, t: int) -> None:
        print(f"{self.label} t={t} {self.x.take()}")


# --- shaped like the radar chain ------------------------------------------------------
class RadarSim(Source):
    """Simulated rotating FMCW radar with odometer, gyro and RTK-GPS."""

    beams = Output(RadarBeam)
    speed = Output(Speed)
    yaw_rate = Output(YawRate)
    gps = Output(Pose2D)
    scenario = Param(str, default="beynes", choices=("beynes", "campus-open", "campus-loop", "semi-urban", "datmo"))
    seed = Param(int, default=0, ge=0)


class FuzzyPairer(Component):
    """Pair up- and down-ramp peaks with six fuzzy rules."""

    beams = Input(RadarBeam)
    targets = Output(Points2D)
    pfa = Param(float, default=1e-4, gt=0, lt=1, doc="false-alarm probability")


class DopplerEgo(Component):
    """Vehicle speed from the Doppler of static targets."""

    targets = Input(Points2D)
    ego = Output(Speed)


class PanoramicBuilder(Component):
    """360 beams to a Cartesian grid, each beam at its own pose."""

    beams = Input(RadarBeam, maxsize=720, overflow="drop_oldest")
    speed = Input(Speed, policy="sampling", history=2.0)
    yaw_rate = Input(YawRate, policy="sampling", history=2.0, angular=True)
    pose = Input(Pose2D, policy="sampling", required=False)
    image = Output(Grid)
    cell_size = Param(float, default=0.2, gt=0, doc="grid cell side, metres")


class SpeckleFilter(Component):
    """Multi-look anti-speckle filter."""

    image = Input(Grid)
    filtered = Output(Grid)
    looks = Param(int, default=4, ge=1, doc="number of co-registered looks averaged")


class RSlam(Component):
    """Dense radar SLAM by map matching."""

    image = Input(Grid, sync="scan", tolerance=0.05)
    speed = Input(Speed, sync="scan", tolerance=0.05)
    pose = Output(Pose2D)
    map = Output(Grid)


class Tracker(Component):
    """DATMO: Kalman tracks of moving targets."""

    targets = Input(Points2D)
    ego = Input(Speed, policy="sampling")
    tracks = Output(ObjectStates)


class TrajectoryEvaluator(Component):
    """Estimated trajectory against ground truth."""

    estimate = Input(Pose2D)
    truth = Input(Pose2D, history=10.0)
    tracks = Input(ObjectStates, required=False)
    report = Param(str, default="out/report")


COMPONENTS = (Ticker, Gain, Boom, Printer, RadarSim, FuzzyPairer, DopplerEgo, PanoramicBuilder,
              SpeckleFilter, RSlam, Tracker, TrajectoryEvaluator)


@hookimpl
def impala_flow_register(registry: Any) -> None:
    for cls in COMPONENTS:
        registry.add_component(cls)
