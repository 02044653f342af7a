"""Radar sources: the live driver interface, the simulator, and recorded real scans.

A live radar implements :class:`RadarDriver`: a :class:`~impala_flow.Source` with
``live = True`` whose ``generate()`` blocks on the hardware and yields one
``(t_ns, "beams", RadarBeam)`` per beam, stamped with ``self.now_ns()`` at acquisition
(the engine maps the monotonic clock to mission time; a receiver with its own clock sets
``clock_offset_ns``). Offline sources (simulator, file readers) yield the same messages
in time order, so every downstream graph runs unchanged on live, simulated or real data.
"""

from __future__ import annotations

import datetime
from collections.abc import Iterator
from typing import Any

from impala_flow import Output, Param, Source
from impala_flow.msgs import Pose2D
from impala_msgs import ObjectStates, RadarBeam, Speed, YawRate

from .datasets.common import (
    DB_PER_COUNT_MAX,
    MAX_MISSION_SPAN_S,
    RANGE_OFFSET_MAX_BINS,
    RANGE_RESOLUTION_MAX_M,
    UNIX_S_MAX,
)
from .datasets.oxford import OXFORD_AZIMUTH_OFFSET_DEG, OXFORD_RANGE_RESOLUTION_M
from .datasets.radiate import RADIATE_AZIMUTH_OFFSET_DEG, RADIATE_GPS_OFFSET_S

__all__ = ["RadarDriver", "OxfordScans", "BoreasScans", "RadiateScans", "Simulator", "SIM_TOPICS",
           "DATASET_TOPICS", "OXFORD_TOPICS", "DATASET_SOURCES"]

#: mission-file topic of each simulator port (``impala-flow simulate`` writes these)
SIM_TOPICS = {"beams": "radar/beams", "odometer": "odometer/speed", "gyro": "gyro/yaw_rate",
              "gps": "gps/pose", "movers": "movers/states"}
#: mission-file topic of each dataset source port (``impala-flow import`` writes these)
DATASET_TOPICS = {"beams": "radar/beams", "truth": "truth/pose"}
OXFORD_TOPICS = DATASET_TOPICS


class RadarDriver(Source):
    """Interface of a live rotating radar: subclass, open the device in ``start()``, and
    yield ``(self.now_ns(), "beams", RadarBeam(...))`` per beam from ``generate()``."""

    live = True
    beams = Output(RadarBeam, doc="one beam per modulation period, stamped at acquisition")
    clock_offset_ns = Param(int, default=0, doc="added to the device's timestamps (its clock vs the mission clock)")


class _NavtechFolderScans(Source):
    """Base of the dataset sources: a Navtech dataset folder read by
    :mod:`impala_radar.datasets`, beams in acquisition order with their own times and
    azimuths, and the dataset's truth poses. ``report`` says what was read (the ``import``
    command prints it); bad input raises :class:`~impala_radar.datasets.DatasetError`."""

    format = ""
    folder = Param(str, path="read", doc="dataset folder (relative: to the graph file's folder)")
    azimuth_offset_deg = Param(float, default=0.0, ge=-360.0, le=360.0, doc="constant added to every beam azimuth, "
                               "counter-clockwise positive (a positive offset turns the scan to the left)")
    range_offset_bins = Param(float, default=0.5, ge=-RANGE_OFFSET_MAX_BINS, le=RANGE_OFFSET_MAX_BINS,
                              doc="range of bin 0 in bins: bin k at (k + this) x resolution; "
                              "0.5 = bin centres (the Navtech SDKs)")
    skip_bad_scans = Param(bool, default=False, doc="skip an unreadable scan (counted and reported with its "
                           "reason) instead of failing")
    db_per_count = Param(float, default=0.5, gt=0.0, le=DB_PER_COUNT_MAX,
                         doc="the pixels' log scale: beams carry linear power "
                         "10^(count x this / 10) (Navtech: 0.5 dB per count)")
    beams = Output(RadarBeam, doc="every kept beam, with its own timestamp and azimuth, in acquisition order")
    truth = Output(Pose2D, doc="ground-truth poses (frame odom: first pose = identity)")

    dataset: Any = None
    report: Any = None

    def _options(self) -> dict[str, Any]:
        return {"azimuth_offset_deg": self.azimuth_offset_deg, "range_offset_bins": self.range_offset_bins}

    def open(self) -> Any:
        """Open the dataset now (checks the folder and the first scan); returns its report."""
        from .datasets import ImportReport, open_dataset

        if self.dataset is None:
            self.report = ImportReport(dataset=self.format, folder=str(self.folder))
            self.dataset = open_dataset(self.format, self.folder, report=self.report, **self._options())
        return self.report

    def start(self) -> None:
        self.open()

    def generate(self) -> Iterator[tuple[int, str, Any]]:
        from .datasets import iter_mission

        yield from iter_mission(self.dataset, self.report, skip_bad=self.skip_bad_scans, db_per_count=self.db_per_count)

    def duration_hint_ns(self) -> int | None:
        try:
            self.open()
        except ValueError:  # a bad folder is reported by start(), not by a progress bar
            return None
        return self.dataset.duration_hint_ns()

    def source_metadata(self) -> dict[str, str]:
        """What was read, as plain key/values (for an ``impala_flow.source`` metadata record)."""
        return {} if self.report is None else self.report.as_metadata()

    def summary(self) -> dict[str, Any]:
        r = self.report
        if r is None:
            return {}
        return {"turns": r.turns, "beams": r.beams, "rows_dropped": sum(r.dropped_rows.values()),
                "scans_skipped": len(r.skipped_scans), "truth_poses": r.truth_poses}


class OxfordScans(_NavtechFolderScans):
    """Real Navtech scans of an Oxford Radar RobotCar folder (``radar/<us>.png`` and
    optionally ``gt/radar_odometry.csv``): beams (power only; rows whose valid flag is not
    255 dropped and counted) and ground-truth poses."""

    format = "oxford"
    # both defaults measured against the sample's ground truth (see impala_radar.datasets.oxford)
    range_resolution_m = Param(float, default=OXFORD_RANGE_RESOLUTION_M, gt=0.0, le=RANGE_RESOLUTION_MAX_M,
                               doc="range per bin: 4.38 cm, measured 4.43 +- 0.05 cm (the README says 4.32)")
    azimuth_offset_deg = Param(float, default=OXFORD_AZIMUTH_OFFSET_DEG, ge=-360.0, le=360.0,
                               doc="constant added to every azimuth, CCW positive: -0.95 deg measured")

    def _options(self) -> dict[str, Any]:
        return {**super()._options(), "range_resolution_m": self.range_resolution_m}


class BoreasScans(_NavtechFolderScans):
    """Real Navtech scans of a Boreas sequence (``radar/<us>.png``, optionally
    ``applanix/radar_poses.csv``): every row kept (column 10 is the chirp direction)."""

    format = "boreas"
    range_resolution_m = Param(float, default=0.0, ge=0.0, le=RANGE_RESOLUTION_MAX_M,
                               doc="range per bin; 0 = by date (0.0596 m before "
                               "2021-09-21, 0.04381 m after)")
    range_offset_bins = Param(float, default=None, ge=-RANGE_OFFSET_MAX_BINS, le=RANGE_OFFSET_MAX_BINS,
                              doc="range of bin 0 in bins: bin k at (k + this) x resolution; "
                              "default (None): -0.31 m, the Boreas documentation's calibrated offset")

    def _options(self) -> dict[str, Any]:
        return {**super()._options(), "range_resolution_m": self.range_resolution_m}


class RadiateScans(_NavtechFolderScans):
    """Real Navtech scans of a RADIATE sequence (``Navtech_Polar/``, ``Navtech_Polar.txt``,
    optionally ``GPS_IMU_Twist/``): beam times from the frame times and the rotation period."""

    format = "radiate"
    range_resolution_m = Param(float, default=0.17361, gt=0.0, le=RANGE_RESOLUTION_MAX_M,
                               doc="range per bin (the dataset's 0.17361 m)")
    azimuth_offset_deg = Param(float, default=RADIATE_AZIMUTH_OFFSET_DEG, ge=-360.0, le=360.0,
                               doc="constant added to every azimuth, CCW positive: -2.3 deg measured")
    rotation = Param(str, default="cw", choices=("cw", "ccw"), doc="sense of increasing columns seen from above "
                     "(cw: checked on the data)")
    retime = Param(bool, default=True, doc="put frames stamped late (the logger fell behind) back on the radar's "
                   "turn clock; False: beam times from the frame stamps as written")
    gps_offset_s = Param(float, default=RADIATE_GPS_OFFSET_S, ge=-60.0, le=60.0,
                         doc="GPS fixes stamped this late against the radar's clock (measured on the Edinburgh "
                         "sequence): a fix stamped t is taken at t - offset")

    def _options(self) -> dict[str, Any]:
        return {**super()._options(), "range_resolution_m": self.range_resolution_m, "rotation": self.rotation,
                "retime": self.retime, "gps_offset_s": self.gps_offset_s}


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


#: source class of each dataset format of ``impala-flow import``
DATASET_SOURCES: dict[str, type[_NavtechFolderScans]] = {
    "oxford": OxfordScans, "boreas": BoreasScans, "radiate": RadiateScans}


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
        self.epoch_ns = epoch_ns(self.epoch_utc)  # checked before the world is built
        if self.built is None:
            self.built = self._scenario()

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
