"""Navtech spinning-radar scans: the public names of the dataset readers.

The readers live in :mod:`impala_radar.datasets` (one module per dataset: ``navtech_png``
for the PNG layout shared by Oxford and Boreas, ``oxford``, ``boreas``, ``radiate``); this
module keeps the names other code imports. Geometry conventions (see
:mod:`impala_radar.datasets.navtech_png`): ``RadarBeam.azimuth_rad = wrap(-a + offset)`` for
the clockwise encoder angle ``a``; bin k at ``(k + 0.5) * range_per_bin_m``
(``RadarConfig.range_offset_m``).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

import impala_msgs
from impala_flow import msgs

from .datasets.common import counts_to_power, iter_mission, navtech_config
from .datasets.navtech_png import NavtechScan, ccw_azimuth, read_navtech_png
from .datasets.oxford import (
    OXFORD_RANGE_RESOLUTION_M,
    OxfordDataset,
    OxfordRelativePoses,
    compose_relative_poses,
    read_oxford_ground_truth,
)

__all__ = [
    "NAVTECH_CTS350X", "NavtechScan", "OxfordRelativePoses", "read_navtech_png",
    "scan_to_beams", "read_oxford_ground_truth", "compose_relative_poses",
    "iter_oxford_folder",
]

NAVTECH_CTS350X = navtech_config("navtech-cts350x-oxford", 3768, OXFORD_RANGE_RESOLUTION_M,
                                 range_offset_m=0.5 * OXFORD_RANGE_RESOLUTION_M, beams_per_turn=400,
                                 rotation_hz=4.0)
"""Navtech CTS350-X of Oxford Radar RobotCar: 4 Hz, 400 beams, 3768 bins of 4.38 cm (measured,
see :data:`~impala_radar.datasets.oxford.OXFORD_RANGE_RESOLUTION_M`), bin k at its centre. (An
import measures the rotation rate on the data instead.)"""


def scan_to_beams(scan: NavtechScan, turn: int, config: impala_msgs.RadarConfig = NAVTECH_CTS350X,
                  azimuth_offset_deg: float = 0.0,
                  db_per_count: float = 0.5) -> list[tuple[int, impala_msgs.RadarBeam]]:
    """Valid rows of ``scan`` as ``(t_ns, RadarBeam)`` in acquisition order (linear power in
    ``up``, :func:`~impala_radar.datasets.common.counts_to_power`; ``down`` empty), azimuth
    ``wrap(-a + radians(azimuth_offset_deg))``."""
    empty = np.zeros(0, dtype=np.float32)
    azimuth = ccw_azimuth(scan.azimuth_rad, azimuth_offset_deg)
    power = counts_to_power(scan.power, db_per_count)
    return [(int(scan.timestamps_ns[i]),
             impala_msgs.RadarBeam(float(azimuth[i]), int(turn), i, power[i], empty, config))
            for i in np.flatnonzero(scan.valid).tolist()]


def iter_oxford_folder(folder: str | Path, **options: float,
                       ) -> Iterator[tuple[int, str, impala_msgs.RadarBeam | msgs.Pose2D]]:
    """``(t_ns, "beams" | "truth", message)`` in time order for an Oxford folder
    (``radar/<us>.png``, optional ``gt/radar_odometry.csv``): every valid beam, and the truth
    poses in frame ``odom`` (identity at the scan before the first one, stamped at the middle
    of each scan). ``options``: :class:`~impala_radar.datasets.oxford.OxfordDataset` parameters."""
    yield from iter_mission(OxfordDataset(folder, **options))
