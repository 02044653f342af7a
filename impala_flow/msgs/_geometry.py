"""Planar geometry messages: poses, velocities, trajectories, grids, point sets."""

from __future__ import annotations

import math
from dataclasses import field

import numpy as np

from ._base import invalid_fields, message

__all__ = ["HEADING_UNKNOWN_VAR_RAD2", "Scalar", "Pose2D",
           "Twist2D", "Trajectory2D", "RelativePose2D", "Grid", "Points2D", "wrap_angle"]


def wrap_angle(a: float | np.ndarray) -> float | np.ndarray:
    """Wrap an angle (or an array of angles) to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


#: A heading variance at or above this (rad^2) means "heading unknown": pi^2 / 3 is the
#: variance of a heading spread evenly over the circle. Truth from a GPS (positions only, the
#: heading known only from the course over ground while moving) marks the others so, and
#: evaluators then score positions only. See :attr:`Pose2D.heading_known`.
HEADING_UNKNOWN_VAR_RAD2 = math.pi**2 / 3.0


@message("impala.Scalar", version=1)
class Scalar:
    """One number with its unit (``"m/s"``, ``"rad/s"``, ``""``)."""

    value: float
    unit: str = ""


@message("impala.Pose2D", version=1)
class Pose2D:
    """A planar pose of ``child`` in ``frame``; ``cov_xyt`` is 3x3 over (x, y, theta) or empty."""

    x_m: float
    y_m: float
    theta_rad: float
    cov_xyt: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    frame: str = "map"

    @classmethod
    def interpolate(cls, a: Pose2D, b: Pose2D, w: float) -> Pose2D:
        """Pose at fraction ``w`` from ``a`` to ``b``: linear in x, y; shortest arc in theta."""
        dt = wrap_angle(b.theta_rad - a.theta_rad)
        cov = a.cov_xyt if w < 0.5 else b.cov_xyt
        return cls(
            a.x_m + w * (b.x_m - a.x_m),
            a.y_m + w * (b.y_m - a.y_m),
            wrap_angle(a.theta_rad + w * dt),
            cov,
            a.frame,
        )

    def as_array(self) -> np.ndarray:
        return np.array([self.x_m, self.y_m, self.theta_rad])

    def invalid_reason(self) -> str | None:
        """Non-finite numbers, or a covariance neither empty nor 3 x 3."""
        why = invalid_fields(self)
        if why is None and np.size(self.cov_xyt) and np.shape(self.cov_xyt) != (3, 3):
            return "cov_xyt neither empty nor 3 x 3"
        return why

    @property
    def heading_known(self) -> bool:
        """False when ``cov_xyt[2, 2] >= HEADING_UNKNOWN_VAR_RAD2``: ``theta_rad`` is then only a
        placeholder (e.g. a GPS fix while the vehicle stands still) and must not be scored."""
        c = self.cov_xyt
        return not (c.shape == (3, 3) and c[2, 2] >= HEADING_UNKNOWN_VAR_RAD2)


@message("impala.Twist2D", version=1)
class Twist2D:
    """Planar velocity in the body frame: forward speed and yaw rate, with a 2x2 covariance."""

    speed_mps: float
    yaw_rate_radps: float
    cov: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))


@message("impala.Trajectory2D", version=1)
class Trajectory2D:
    """A whole planar trajectory: timestamps (int ns) and N x 3 poses (x_m, y_m, theta_rad)."""

    t_ns: np.ndarray
    xyt: np.ndarray
    frame: str = "map"


@message("impala.RelativePose2D", version=1)
class RelativePose2D:
    """A constraint between two poses of one trajectory, each named by its time (int ns):
    the pose at ``to_t_ns`` expressed in the frame of the pose at ``from_t_ns``, with its
    3x3 covariance over (x, y, theta). ``kind`` says where it comes from: ``odometry``,
    ``registration`` (consecutive scans), ``loop`` (a loop closure accepted by its
    producer), ``loop_rejected`` (a candidate its producer's gate refused)."""

    from_t_ns: int
    to_t_ns: int
    x_m: float
    y_m: float
    theta_rad: float
    cov_xyt: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    kind: str = "registration"


@message("impala.Grid", version=1)
class Grid:
    """A 2-D raster (row = y, column = x) of ``cell_m`` cells, cell (0, 0) centred at origin.

    ``origin_x_m``/``origin_y_m`` are the centre of cell (0, 0) in ``frame``. ``pose`` is
    the sensor pose the grid was built at (for sensor-centred images), or ``None``.
    """

    data: np.ndarray
    cell_m: float
    origin_x_m: float
    origin_y_m: float
    frame: str = "map"
    pose: Pose2D | None = None

    def invalid_reason(self) -> str | None:
        """Non-finite numbers (see :func:`~impala_flow.msgs.invalid_fields`), ``cell_m <= 0`` or
        ``data`` not 2-D."""
        why = invalid_fields(self)
        if why is None and not self.cell_m > 0:
            return "cell_m <= 0"
        if why is None and np.ndim(self.data) != 2:
            return "data not 2-D"
        return why


@message("impala.Points2D", version=1)
class Points2D:
    """A set of planar points (N x 2, metres) with one value per point (intensity, RCS...)."""

    xy_m: np.ndarray
    value: np.ndarray
    frame: str = "map"
