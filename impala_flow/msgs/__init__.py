"""Standard message types shared by the engine and every plugin.

See :mod:`impala_flow.msgs._base` for the contract a message type follows.
"""

from ._base import freeze, invalid_fields, is_message, message, schema_name, schema_version
from ._geometry import (
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
    CHIRP_DOWN,
    CHIRP_UP,
    SPEED_OF_LIGHT_MPS,
    ObjectStates,
    RadarBeam,
    RadarBeamV1,
    RadarConfig,
    RadarDetections,
    RadarScan,
    Speed,
    TrackExistence,
    YawRate,
    upgrade_radar_beam_v1,
)

BUILTIN_TYPES: tuple[type, ...] = (
    Scalar, Pose2D, Twist2D, Trajectory2D, RelativePose2D, Grid, Points2D,
    RadarConfig, RadarBeam, RadarScan, RadarDetections, Speed, YawRate, ObjectStates,
    TrackExistence,
)

#: older versions of standard types, read from recordings and upgraded: (old type, upgrade function)
LEGACY_TYPES: tuple[tuple[type, object], ...] = ((RadarBeamV1, upgrade_radar_beam_v1),)

__all__ = [
    "message", "is_message", "schema_name", "schema_version", "freeze", "invalid_fields", "wrap_angle",
    "HEADING_UNKNOWN_VAR_RAD2",
    "Scalar", "Pose2D", "Twist2D", "Trajectory2D", "RelativePose2D", "Grid", "Points2D",
    "RadarConfig", "RadarBeam", "RadarScan", "RadarDetections", "Speed", "YawRate", "ObjectStates",
    "TrackExistence", "SPEED_OF_LIGHT_MPS", "BUILTIN_TYPES", "LEGACY_TYPES", "CHIRP_UP", "CHIRP_DOWN",
]
