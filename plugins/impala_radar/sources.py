"""Radar sources: the live driver interface, the simulator, and recorded real scans.

A live radar implements :class:`RadarDriver`: a :class:`~impala_flow.Source` with
``live = True`` whose ``generate()`` blocks on the hardware and yields one
``(t_ns, "beams", RadarBeam)`` per beam, stamped with ``self.now_ns()`` at acquisition
(the engine maps the monotonic clock to mission time; a receiver with its own clock sets
``clock_offset_ns``). Offline sources (simulator, file readers) yield the same messages
in time order, so every downstream graph runs unchanged on live, simulated or real data.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

from impala_flow import Output, Param, Source
from impala_flow.msgs import ObjectStates, Pose2D, RadarBeam, Speed, YawRate

from .navtech import NAVTECH_CTS350X, iter_oxford_folder, read_navtech_png

__all__ = ["RadarDriver", "OxfordScans", "Simulator", "SIM_TOPICS", "OXFORD_TOPICS"]

#: mission-file topic of each simulator port (``impala-flow simulate`` writes these)
SIM_TOPICS = {"beams": "radar/beams", "odometer": "odometer/speed", "gyro": "gyro/yaw_rate",
              "gps": "gps/pose", "movers": "movers/states"}
#: mission-file topic of each Oxford port (``impala-flow import oxford`` writes these)
OXFORD_TOPICS = {"beams": "radar/beams", "truth": "truth/pose"}


class RadarDriver(Source):
    """Interface of a live rotating radar: subclass, open the device in ``start()``, and
    yield ``(self.now_ns(), "beams", RadarBeam(...))`` per beam from ``generate()``."""

    live = True
    beams = Output(RadarBeam, doc="one beam per modulation period, stamped at acquisition")
    clock_offset_ns = Param(int, default=0, doc="added to the device's timestamps (its clock vs the mission clock)")


class OxfordScans(Source):
    """Real Navtech scans of an Oxford Radar RobotCar folder (``radar/<us>.png`` and
    optionally ``gt/radar_odometry.csv``): beams (power only) and ground-truth poses."""

    folder = Param(str, doc="dataset folder holding radar/ and gt/")
    beams = Output(RadarBeam, doc="every valid beam, with its own timestamp and azimuth")
    truth = Output(Pose2D, doc="ground-truth pose at the middle of each scan (frame odom)")

    def start(self) -> None:
        if not (Path(self.folder) / "radar").is_dir():
            raise FileNotFoundError(f"{self.folder}: no radar/ folder of Navtech PNG scans")

    def generate(self) -> Iterator[tuple[int, str, Any]]:
        yield from iter_oxford_folder(self.folder, NAVTECH_CTS350X)

    def duration_hint_ns(self) -> int | None:
        pngs = sorted((Path(self.folder) / "radar").glob("*.png"))
        if len(pngs) < 2:
            return None
        first, last = read_navtech_png(pngs[0]), read_navtech_png(pngs[-1])
        return int(last.timestamps_ns[-1] - first.timestamps_ns[0])


class Simulator(Source):
    """The physically based FMCW rotating-radar simulator on a scenario world.

    ``scenario`` is a name under ``graphs/scenarios/`` (beynes, campus-open, campus-loop,
    semi-urban, datmo) or a path to a scenario YAML file.
    """

    scenario = Param(str, default="beynes", doc="scenario name or YAML file")
    seed = Param(int, default=-1, doc="random seed of the world and the sensor noise (-1: the scenario's)")
    duration_s = Param(float, default=0.0, ge=0.0, doc="mission duration (0: the scenario's)")
    beams = Output(RadarBeam, doc="radar beams, each at the vehicle pose of its own time")
    odometer = Output(Speed, doc="odometer speed (scale error, noise, slip)")
    gyro = Output(YawRate, doc="gyrometer yaw rate (bias, noise, bias random walk)")
    gps = Output(Pose2D, doc="RTK-GPS truth poses (2 cm, 10 Hz)")
    movers = Output(ObjectStates, doc="truth of every moving object (10 Hz)")

    def _scenario(self) -> Any:
        from .sim.scenario import load_scenario

        return load_scenario(self.scenario, seed=None if self.seed < 0 else self.seed,
                             duration_s=self.duration_s or None)

    built: Any = None  # the loaded scenario (world, trajectory, sensors), built once

    def start(self) -> None:
        if self.built is None:
            self.built = self._scenario()

    def generate(self) -> Iterator[tuple[int, str, Any]]:
        yield from self.built.simulate()

    def duration_hint_ns(self) -> int | None:
        if self.built is None:
            self.built = self._scenario()
        return int(self.built.duration_ns)
