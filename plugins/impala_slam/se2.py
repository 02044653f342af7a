"""Planar rigid transforms on (x_m, y_m, theta_rad) triples: compose (+), inverse, between."""

from __future__ import annotations

import math

from impala_flow.msgs import wrap_angle

__all__ = ["compose", "inverse", "between", "wrap"]


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
