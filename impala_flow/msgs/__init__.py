"""Standard message types shared by the engine and every plugin.

See :mod:`impala_flow.msgs._base` for the contract a message type follows.
"""

from ._base import freeze, is_message, message, schema_name, schema_version
from .geometry import (
    HEADING_UNKNOWN_VAR_RAD2,
    Grid,
    Points2D,
    Pose2D,
    RelativePose2D,
    Scalar,
    Trajectory2D,
    Twist2D,
    wrap_angle,
)
from .sensors import (
    SPEED_OF_LIGHT_MPS,
    ObjectStates,
    RadarBeam,
    RadarConfig,
    RadarDetections,
    RadarScan,
    Speed,
    TrackExistence,
    YawRate,
)

BUILTIN_TYPES: tuple[type, ...] = (
    Scalar, Pose2D, Twist2D, Trajectory2D, RelativePose2D, Grid, Points2D,
    RadarConfig, RadarBeam, RadarScan, RadarDetections, Speed, YawRate, ObjectStates,
    TrackExistence,
)

__all__ = [
    "message", "is_message", "schema_name", "schema_version", "freeze", "wrap_angle", "HEADING_UNKNOWN_VAR_RAD2",
    "Scalar", "Pose2D", "Twist2D", "Trajectory2D", "RelativePose2D", "Grid", "Points2D",
    "RadarConfig", "RadarBeam", "RadarScan", "RadarDetections", "Speed", "YawRate", "ObjectStates",
    "TrackExistence", "SPEED_OF_LIGHT_MPS", "BUILTIN_TYPES",
]
