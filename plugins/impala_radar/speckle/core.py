"""``radar.SpeckleFilter``: multi-look anti-speckle filtering (seed 1 §2.3) and the
thresholding of the Fourier-Mellin registration's step 2 (seed 2, Algorithm 1).

Multi-look: the last ``looks`` images (one per turn) are co-registered into the vehicle
frame of the newest from their dead-reckoned poses (``Grid.pose``, frame ``odom``) with
``cv2.warpAffine``, then averaged cell by cell over the looks that observed the cell.
Speckle of independent looks averages out: on homogeneous clutter the equivalent number
of looks ENL = mean^2 / var grows as N (ENL = 1 for fully developed speckle); bilinear
resampling of sub-cell shifts smooths a little more. A point target at the same place in
every look keeps its level.

Thresholding (step 2 of Algorithm 1): cells below ``threshold`` x the mean of the observed
cells (``threshold_mode = "mean"``), or below the ``threshold`` quantile of them
(``"quantile"``), are set to 0.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from impala_flow.msgs import Grid

__all__ = ["registration_affine", "multilook", "threshold_image", "enl"]

INTERPOLATIONS = {"linear": cv2.INTER_LINEAR, "nearest": cv2.INTER_NEAREST}


def enl(intensity: np.ndarray) -> float:
    """Equivalent number of looks mean^2 / var of an intensity sample."""
    x = np.asarray(intensity, float)
    return float(x.mean() ** 2 / x.var())


def registration_affine(src: Grid, dst: Grid) -> np.ndarray:
    """2x3 affine mapping pixel (column, row) of ``src`` to pixel of ``dst`` from their
    poses: p_dst = inv(P_dst) o P_src p_src, pixels = (x - origin) / cell."""
    ps, pd = src.pose, dst.pose
    da = ps.theta_rad - pd.theta_rad
    a = np.array([[math.cos(da), -math.sin(da)], [math.sin(da), math.cos(da)]])
    c, s = math.cos(pd.theta_rad), math.sin(pd.theta_rad)
    dx, dy = ps.x_m - pd.x_m, ps.y_m - pd.y_m
    b = np.array([c * dx + s * dy, -s * dx + c * dy])
    o_src = np.array([src.origin_x_m, src.origin_y_m])
    o_dst = np.array([dst.origin_x_m, dst.origin_y_m])
    scale = src.cell_m / dst.cell_m
    m = np.empty((2, 3))
    m[:, :2] = a * scale
    m[:, 2] = (a @ o_src + b - o_dst) / dst.cell_m
    return m


def multilook(images: list[Grid], interpolation: str = "linear") -> tuple[np.ndarray, np.ndarray]:
    """Mean of ``images`` co-registered into the frame of the last one; also the number of
    looks that observed each cell."""
    ref = images[-1]
    h, w = ref.data.shape
    acc = np.zeros((h, w), np.float32)
    cnt = np.zeros((h, w), np.uint8 if len(images) < 256 else np.float32)  # looks per cell: small integers
    for g in images:
        if g is ref:
            acc += g.data
            cnt += g.data > 0
            continue
        m = registration_affine(g, ref)
        acc += cv2.warpAffine(np.ascontiguousarray(g.data, np.float32), m, (w, h),
                              flags=INTERPOLATIONS[interpolation], borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        # footprint of the look (nearest: a cell is observed or not)
        cnt += cv2.warpAffine((g.data > 0).view(np.uint8), m, (w, h), flags=cv2.INTER_NEAREST,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    from ._jit import mean_of_looks  # here: numba is imported at the first turn, not with the plugin

    out, cnt_f = np.empty((h, w), np.float32), np.empty((h, w), np.float32)
    mean_of_looks(acc, cnt, out, cnt_f)  # acc / cnt, 0 where no look observed the cell
    return out, cnt_f


def threshold_image(data: np.ndarray, mode: str, threshold: float) -> np.ndarray:
    """FMT step 2: zero the cells below the threshold (see the module docstring)."""
    if mode == "none" or threshold <= 0.0:
        return data
    observed = data[data > 0]
    if observed.size == 0:
        return data
    level = threshold * observed.mean() if mode == "mean" else np.quantile(observed, threshold)
    return np.where(data >= level, data, np.float32(0.0)).astype(np.float32)
