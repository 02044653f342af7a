"""Message types: the contract every message follows, and the domain-free geometry types.

See :mod:`impala_flow.msgs._base` for the contract a message type follows. Domain messages
(radar beams, odometer, tracked objects) live in message packages beside the engine (the
radar chain's is ``impala_msgs``), declared in the ``impala_flow.messages`` entry point group
so every registry and recording reader knows them (:func:`installed_types`).
"""

from ._base import freeze, freezer_for, invalid_fields, is_message, message, schema_name, schema_version
from ._catalog import GROUP, MessagePackage, installed_packages, installed_types
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

#: the engine's own message types
BUILTIN_TYPES: tuple[type, ...] = (Scalar, Pose2D, Twist2D, Trajectory2D, RelativePose2D, Grid, Points2D)

__all__ = [
    "message", "is_message", "schema_name", "schema_version", "freeze", "freezer_for", "invalid_fields", "wrap_angle",
    "HEADING_UNKNOWN_VAR_RAD2",
    "Scalar", "Pose2D", "Twist2D", "Trajectory2D", "RelativePose2D", "Grid", "Points2D",
    "BUILTIN_TYPES", "GROUP", "MessagePackage", "installed_packages", "installed_types",
]
