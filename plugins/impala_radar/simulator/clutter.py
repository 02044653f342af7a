"""Distributed clutter and vegetation: grazing-angle law, developed speckle, moving leaves.

**Grazing angle (constant-gamma).** The backscatter of rough ground falls with the grazing
angle psi (Ulaby & Dobson, *Handbook of Radar Scattering Statistics for Terrain*)::

    sigma0(psi) = gamma sin(psi),   sin(psi) = (h - z) / R_slant

A world's clutter is built with sigma0 at a reference grazing angle psi_ref
(``RadarParams.grazing_ref_deg``, 5 deg), i.e. gamma = sigma0_ref / sin(psi_ref); each echo
of a distributed scatterer (``World.area_m2 > 0``) is scaled by sin(psi) / sin(psi_ref)
(:func:`grazing_factor`). With the IMPALA radar 1.3 m high, psi = 5 deg at 14.9 m: clutter
at 5 m is 5.5 dB stronger, at 100 m 8.3 dB weaker than sigma0_ref.

**Developed speckle.** Clutter points are laid out one per tile of side s = 1/sqrt(rho)
(stratified, :meth:`WorldBuilder.clutter`) holding the tile's mean RCS; the simulator gives
each a complex Gaussian amplitude (exponential RCS drawn from a hash of its index, uniform
phase). A sum of complex Gaussians is complex Gaussian, so a resolution cell's
amplitude is exactly Rayleigh (std/mean = sqrt(4/pi - 1) = 0.523) as soon as the cell's
summed pattern weight sum_i |h_i|^2 is uniform, i.e. the points are spaced finer than the
resolution (range: dR = c / (2 dF); azimuth: half the beam footprint theta_3 R). Near the
radar the world's density is too low for that (IMPALA: s = 1.41 m for 0.5 /m^2 against a
0.7 m footprint at 10 m), so within ``RadarParams.speckle_range_m`` of a turn's centre each
clutter tile is split into q x q stratified sub-points (:func:`split_tiles`),

    q = ceil(s / d),   d = min(dR, theta_3 R / 2)   (at most ``speckle_max_split``)

each with an exponential share of the tile's RCS and a uniform phase. The split is drawn
from a hash of the tile's index (deterministic: a static radar sees the same speckle every
turn). Beyond that range the clutter is K-distributed (few points per cell), as far clutter
at low resolution is.

**Moving leaves.** Between turns the leaves of trees and bushes move: each vegetation
scatterer gets per turn a phase jitter N(0, (4 pi sigma_x / lambda)^2) (sigma_x =
``RadarParams.vegetation_motion_m``, rms displacement along the line of sight) and a
log-normal RCS factor of mean 1 and ``vegetation_rcs_jitter_db`` standard deviation in dB
(:func:`vegetation_jitter`), so the map of a wood is not perfectly repeatable while walls,
trunks and posts are.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["grazing_factor", "split_tiles", "vegetation_jitter", "hash_uniform"]

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
AZIMUTH_SPACING = 0.5  # sub-point spacing in azimuth, in beam footprints theta_3 R


def hash_uniform(key: np.ndarray, stream: int) -> np.ndarray:
    """Uniform [0, 1) floats from integer keys (splitmix64), one independent stream each."""
    with np.errstate(over="ignore"):
        z = key.astype(np.uint64) * _GOLDEN + np.uint64(stream + 1) * np.uint64(0xD1B54A32D192ED03)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) * (1.0 / (1 << 53))


def grazing_factor(range_m, dz_m, area_m2, ref_grazing_deg: float | None):
    """sin(psi) / sin(psi_ref) for distributed scatterers (area > 0), 1 for the others."""
    if ref_grazing_deg is None:
        return np.ones(np.shape(range_m))
    sin_psi = np.abs(dz_m) / range_m
    return np.where(area_m2 > 0.0, sin_psi / math.sin(math.radians(ref_grazing_deg)), 1.0)


def split_tiles(index, cx_m, cy_m, area_m2, rcs_m2, dist_m, range_resolution_m: float,
                beam_width_rad: float, max_split: int):
    """Sub-points of the clutter tiles that the resolution at ``dist_m`` needs split.

    Returns ``(parent, x, y, rcs, phase)`` for the sub-points (parent = position in the
    input arrays) and the bool mask of the tiles replaced by them.
    """
    side = np.sqrt(area_m2)
    d_need = np.minimum(range_resolution_m, AZIMUTH_SPACING * beam_width_rad * np.maximum(dist_m, 1e-3))
    q = np.minimum(np.ceil(side / d_need - 1e-9), max_split).astype(np.int64)
    split = (area_m2 > 0.0) & (q > 1)
    if not split.any():
        e = np.zeros(0)
        return np.zeros(0, np.intp), e, e, e, e, split
    pos = np.nonzero(split)[0]
    qq = q[pos]
    n_sub = qq * qq
    parent = np.repeat(pos, n_sub)
    k = np.arange(len(parent)) - np.repeat(np.cumsum(n_sub) - n_sub, n_sub)  # sub-index in its tile
    qp = qq.repeat(n_sub)
    key = index[parent].astype(np.uint64) * np.uint64(4096) + k.astype(np.uint64)
    u1, u2, u3, u4 = (hash_uniform(key, s) for s in range(4))
    s_p = side[parent]
    x = cx_m[parent] + s_p * (((k % qp) + u1) / qp - 0.5)
    y = cy_m[parent] + s_p * (((k // qp) + u2) / qp - 0.5)
    rcs = rcs_m2[parent] / (qp * qp) * -np.log1p(-u3)  # exponential share: complex Gaussian
    return parent, x, y, rcs, 2.0 * math.pi * u4, split


def vegetation_jitter(n: int, rng: np.random.Generator, lambda_m: float, motion_m: float,
                      rcs_jitter_db: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-turn (phase offset rad, RCS factor) of ``n`` vegetation scatterers (module doc)."""
    phase = rng.normal(0.0, 4.0 * math.pi * motion_m / lambda_m, n) if motion_m > 0 else np.zeros(n)
    s = rcs_jitter_db * math.log(10.0) / 10.0
    factor = np.exp(rng.normal(-0.5 * s * s, s, n)) if s > 0 else np.ones(n)
    return phase, factor
