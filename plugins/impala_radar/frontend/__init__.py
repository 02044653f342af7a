"""Radar front end (RADAR.md items 2-5): fuzzy up/down pairing, Doppler ego-velocity,
panoramic images with motion correction, multi-look anti-speckle filtering, a report, and the
strongest returns of each beam as points (for point-based odometries such as kiss-icp)."""

from .ego_velocity import EgoVelocity, fit_ego_velocity
from .extractor import PeakExtractor, extract_peaks
from .pairer import FuzzyPairer
from .pairing import pair_turn
from .panoramic import relative_beam_poses, scan_to_grid
from .panoramic_builder import PanoramicBuilder
from .speckle import SpeckleFilter

__all__ = [
    "FuzzyPairer", "EgoVelocity", "PanoramicBuilder", "SpeckleFilter", "FrontendReport", "PeakExtractor",
    "extract_peaks",
    "pair_turn", "fit_ego_velocity", "scan_to_grid", "relative_beam_poses",
]


def __getattr__(name: str):
    if name == "FrontendReport":  # matplotlib only when the report is used
        from .report import FrontendReport

        return FrontendReport
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
