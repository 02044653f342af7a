"""Synthetic beams of a Navtech-like radar driving past point reflectors, and the degenerate
versions of them a careless recording gives (all-zero, all-NaN, all-inf, 10 % NaN or inf
beams, one beam per turn): the inputs of tests/slam/test_degenerate_inputs.py."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from impala_flow.msgs import Pose2D
from impala_msgs import RadarBeam
from impala_radar.simulator.presets import NAVTECH

#: NAVTECH with fewer bins (1000 x 4.38 cm = 43.8 m): the same geometry, a quarter of the work
CONFIG = dataclasses.replace(NAVTECH, n_bins=1000, range_max_m=1000 * NAVTECH.range_per_bin_m)
SPEED_MPS = 5.0
YAW_RATE_RADPS = 0.05
CASES = ("clean", "zero", "nan", "inf", "nan10", "inf10", "single")


def navtech_beams(turns: int = 5, seed: int = 0, config=CONFIG) -> list[tuple[int, str, RadarBeam]]:
    """(t_ns, "beams", beam) of ``turns`` turns: a unicycle at SPEED_MPS and YAW_RATE_RADPS among
    200 static point reflectors 5-40 m away, power = exponential floor (mean 1) + each echo
    (30-40 dB) spread over the antenna beam (Gaussian, 1.8 deg at 3 dB) and 1.5 bins in range."""
    rng = np.random.default_rng(seed)
    n = 200
    r0, a0 = rng.uniform(5.0, 40.0, n), rng.uniform(-math.pi, math.pi, n)
    pts = np.c_[r0 * np.cos(a0) + 0.5 * SPEED_MPS * turns / config.rotation_hz, r0 * np.sin(a0)]
    amp = 10.0 ** rng.uniform(3.0, 4.0, n)
    sigma_az = config.beam_width_rad / 2.355
    k = np.arange(config.n_bins)
    out = []
    m = config.beams_per_turn
    dt_s = 1.0 / (config.rotation_hz * m)
    for j in range(turns * m):
        t = 1.0 + j * dt_s
        x, y, th = pose_at(t - 1.0)
        az = -2.0 * math.pi * (j % m) / m  # clockwise, as Navtech
        rel = pts - (x, y)
        c, s = math.cos(th), math.sin(th)
        bx, by = c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1]
        d_az = np.angle(np.exp(1j * (np.arctan2(by, bx) - az)))
        hit = np.abs(d_az) < 3 * sigma_az
        power = rng.exponential(1.0, config.n_bins)
        if hit.any():
            kr = np.asarray(config.bin_of_range(np.hypot(bx[hit], by[hit])))
            g = amp[hit] * np.exp(-0.5 * (d_az[hit] / sigma_az) ** 2)
            power += (g[:, None] * np.exp(-0.5 * ((k[None, :] - kr[:, None]) / 1.5) ** 2)).sum(axis=0)
        out.append((int(round(t * 1e9)), "beams",
                    RadarBeam(az, j // m, j % m, power.astype(np.float32), np.zeros(0, np.float32), config)))
    return out


def pose_at(t_s: float) -> tuple[float, float, float]:
    """The unicycle's pose (x, y, heading) ``t_s`` seconds after the first beam (exact arc)."""
    th = YAW_RATE_RADPS * t_s
    chord = SPEED_MPS * t_s * (np.sinc(th / (2 * math.pi)) if th else 1.0)
    return chord * math.cos(th / 2), chord * math.sin(th / 2), th


def truth_poses(turns: int = 5, config=CONFIG) -> list[tuple[int, str, Pose2D]]:
    """(t_ns, "truth", pose) every 0.05 s over the beams of :func:`navtech_beams`, frame map."""
    return [(int(round((1.0 + t) * 1e9)), "truth", Pose2D(*pose_at(t), frame="map"))
            for t in np.arange(0.0, turns / config.rotation_hz, 0.05)]


def corrupt(beams: list[tuple[int, str, RadarBeam]], case: str, seed: int = 1) -> list[tuple[int, str, RadarBeam]]:
    """The beams of ``case``: ``clean``; ``zero``, ``nan``, ``inf`` (every bin of every beam);
    ``nan10`` / ``inf10`` (every bin of 10 % of the beams, chosen at random); ``single`` (one
    beam per turn)."""
    if case == "clean":
        return beams
    if case == "single":
        return [b for b in beams if b[2].index == 0]
    rng = np.random.default_rng(seed)
    fill = {"zero": 0.0, "nan": np.nan, "inf": np.inf, "nan10": np.nan, "inf10": np.inf}[case]
    bad = rng.random(len(beams)) < 0.1 if case.endswith("10") else np.ones(len(beams), bool)
    return [(t, p, dataclasses.replace(b, up=np.full_like(b.up, fill)) if bad[i] else b)
            for i, (t, p, b) in enumerate(beams)]
