"""The dataset sources ``radar.OxfordScans``, ``radar.BoreasScans``, ``radar.RadiateScans``.

Each reads a dataset folder with the readers of this package (:func:`.formats.open_dataset`) and
yields the beams in acquisition order, with their own times and azimuths, and the dataset's truth
poses, as a live radar would give them.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from impala_flow import Output, Param, Source
from impala_flow.msgs import Pose2D
from impala_msgs import RadarBeam

from .common import (
    DB_PER_COUNT_MAX,
    RANGE_OFFSET_MAX_BINS,
    RANGE_RESOLUTION_MAX_M,
)
from .oxford import OXFORD_AZIMUTH_OFFSET_DEG, OXFORD_RANGE_RESOLUTION_M
from .radiate import RADIATE_AZIMUTH_OFFSET_DEG, RADIATE_GPS_OFFSET_S

__all__ = ["OxfordScans", "BoreasScans", "RadiateScans", "DATASET_TOPICS", "OXFORD_TOPICS", "DATASET_SOURCES"]

#: mission-file topic of each dataset source port (``impala-flow import`` writes these)
DATASET_TOPICS = {"beams": "radar/beams", "truth": "truth/pose"}


OXFORD_TOPICS = DATASET_TOPICS


class _NavtechFolderScans(Source):
    """Base of the dataset sources: a Navtech dataset folder read by
    :mod:`impala_radar.datasets`, beams in acquisition order with their own times and
    azimuths, and the dataset's truth poses. ``report`` says what was read (the ``import``
    command prints it); bad input raises :class:`~impala_radar.datasets.common.DatasetError`."""

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
        from .common import ImportReport
        from .formats import open_dataset

        if self.dataset is None:
            self.report = ImportReport(dataset=self.format, folder=str(self.folder))
            self.dataset = open_dataset(self.format, self.folder, report=self.report, **self._options())
        return self.report

    def start(self) -> None:
        self.open()

    def generate(self) -> Iterator[tuple[int, str, Any]]:
        from .common import iter_mission

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


#: source class of each dataset format of ``impala-flow import``
DATASET_SOURCES: dict[str, type[_NavtechFolderScans]] = {
    "oxford": OxfordScans, "boreas": BoreasScans, "radiate": RadiateScans}
