"""``radar.Simulator``: a simulated mission as a source (beams, odometer, gyro, GPS, movers).

The scenario (:mod:`.scenario`: world, route, radar preset, sensors) is loaded at start; the
radar physics are :mod:`.core` (:func:`~.core.simulate`) and the modules next to it (antenna,
clutter, receiver, spectra, world, scenes, vehicle, sensors).
"""

from __future__ import annotations

import datetime
from collections.abc import Iterator
from typing import Any

from impala_flow import Output, Param, Source
from impala_flow.msgs import Pose2D
from impala_msgs import ObjectStates, RadarBeam, Speed, YawRate

from ..datasets.common import (
    MAX_MISSION_SPAN_S,
    UNIX_S_MAX,
)

__all__ = ["Simulator", "SIM_TOPICS"]


#: mission-file topic of each simulator port (``impala-flow simulate`` writes these)
SIM_TOPICS = {"beams": "radar/beams", "odometer": "odometer/speed", "gyro": "gyro/yaw_rate",
              "gps": "gps/pose", "movers": "movers/states"}


#: start of simulated missions unless told otherwise (Foxglove's timeline shows real dates)
DEFAULT_EPOCH = "2026-01-01T00:00:00Z"


def epoch_ns(text: str) -> int:
    """UNIX time in ns of an ISO 8601 date and time (UTC when no zone is given); "" -> 0."""
    if not text.strip():
        return 0
    try:
        d = datetime.datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
    except ValueError:
        raise ValueError(f"epoch_utc {text!r} is not an ISO 8601 date and time "
                         "(e.g. 2026-01-01T00:00:00Z)") from None
    if d.tzinfo is None:
        d = d.replace(tzinfo=datetime.UTC)
    delta = d - datetime.datetime(1970, 1, 1, tzinfo=datetime.UTC)
    t_ns = (delta.days * 86_400 + delta.seconds) * 1_000_000_000 + delta.microseconds * 1_000
    if not 0 <= t_ns <= UNIX_S_MAX * 1_000_000_000:  # mission times are int64 ns, never negative
        raise ValueError(f"epoch_utc {text!r}: expected a date from 1970 to 2100")
    return t_ns


class Simulator(Source):
    """The physically based FMCW rotating-radar simulator on a scenario world.

    ``scenario`` is a name under ``graphs/scenarios/`` (beynes, campus-open, campus-loop,
    semi-urban, datmo, urban) or a path to a scenario YAML file. Samples are stamped from
    ``epoch_utc`` (UNIX time in ns: a recording's timeline shows that date in Foxglove);
    ``epoch_utc: ""`` starts the mission at t = 0. The simulated world is the same whatever
    the epoch: only the stamps move.
    """

    scenario = Param(str, default="beynes", path="read_or_name", doc="scenario name or YAML file")
    seed = Param(int, default=-1, doc="random seed of the world and the sensor noise (-1: the scenario's)")
    duration_s = Param(float, default=0.0, ge=0.0, le=MAX_MISSION_SPAN_S, doc="mission duration (0: the scenario's; "
                       "at most a day)")
    epoch_utc = Param(str, default=DEFAULT_EPOCH, doc="UTC date and time of the mission's start "
                      "(ISO 8601, e.g. 2026-01-01T00:00:00Z); empty: t = 0")
    threads = Param(int, default=0, ge=0, le=64, doc="threads sharing each antenna turn's work (0: the cores, "
                    "at most 2); the mission is the same bit for bit whatever their number")
    beams = Output(RadarBeam, doc="radar beams, each at the vehicle pose of its own time")
    odometer = Output(Speed, doc="odometer speed (scale error, noise, slip)")
    gyro = Output(YawRate, doc="gyrometer yaw rate (bias, noise, bias random walk)")
    gps = Output(Pose2D, doc="RTK-GPS truth poses (2 cm, 10 Hz)")
    movers = Output(ObjectStates, doc="truth of every moving object (10 Hz)")

    def _scenario(self) -> Any:
        from .scenario import load_scenario

        return load_scenario(self.scenario, seed=None if self.seed < 0 else self.seed,
                             duration_s=self.duration_s or None)

    built: Any = None  # the loaded scenario (world, trajectory, sensors), built once

    def start(self) -> None:
        self.epoch_ns = epoch_ns(self.epoch_utc)  # checked before the world is built
        if self.built is None:
            self.built = self._scenario()
        self.built.threads = self.threads or None

    def generate(self) -> Iterator[tuple[int, str, Any]]:
        e = self.epoch_ns
        if not e:
            yield from self.built.simulate()
            return
        for t, port, msg in self.built.simulate():
            yield t + e, port, msg

    def duration_hint_ns(self) -> int | None:
        if self.built is None:
            self.built = self._scenario()
        return int(self.built.duration_ns)
