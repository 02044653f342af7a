"""Planar rigid transforms on (x_m, y_m, theta_rad) triples: compose (+), inverse, between, and
the exponential and logarithm (``exp``, ``log``), and an increment repeated along its
constant-twist arc (``repeat``)."""

from __future__ import annotations

import math

from impala_flow.msgs import wrap_angle

__all__ = ["compose", "inverse", "between", "log", "exp", "repeat", "wrap"]


wrap = wrap_angle  # angle wrapped to [-pi, pi)


def compose(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float, float]:
    """a (+) b: pose ``b`` expressed in frame ``a``, brought to a's parent frame."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], wrap(a[2] + b[2])


def inverse(a: tuple[float, float, float]) -> tuple[float, float, float]:
    """(-)a, so that a (+) (-)a is the identity."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return -c * a[0] - s * a[1], s * a[0] - c * a[1], wrap(-a[2])


def between(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float, float]:
    """(-)a (+) b: pose ``b`` in the frame of pose ``a``."""
    return compose(inverse(a), b)


def _arc(theta: float) -> tuple[float, float]:
    """(sin t / t, (1 - cos t) / t): the SE(2) exponential's V matrix entries (series near 0)."""
    if abs(theta) < 1e-6:
        return 1.0 - theta * theta / 6.0, 0.5 * theta
    return math.sin(theta) / theta, (1.0 - math.cos(theta)) / theta


def log(d: tuple[float, float, float]) -> tuple[float, float, float]:
    """The constant twist ``(v_x, v_y, omega)`` over unit time whose exponential is ``d``."""
    a, b = _arc(d[2])
    det = a * a + b * b
    return (a * d[0] + b * d[1]) / det, (-b * d[0] + a * d[1]) / det, d[2]  # V(theta)^-1 (x, y)


def exp(v: tuple[float, float, float]) -> tuple[float, float, float]:
    """The increment (x, y, theta) of the constant twist ``v = (v_x, v_y, omega)`` over unit time."""
    a, b = _arc(v[2])
    return a * v[0] - b * v[1], b * v[0] + a * v[1], wrap(v[2])


def repeat(d: tuple[float, float, float], w: float) -> tuple[float, float, float]:
    """exp(w log d): the increment ``d`` continued for ``w`` times its duration at the same
    forward, lateral and yaw rates (a circular arc), e.g. a constant-velocity prediction
    over a gap of several intervals. Scaling (x, y, theta) by ``w`` instead keeps the first
    increment's chord direction: 18 m through a 25 deg bend lands 4 m off the road."""
    vx, vy, om = log(d)
    return exp((w * vx, w * vy, w * om))
