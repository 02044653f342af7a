"""R-SLAM map matching on real Navtech scans (Oxford Radar RobotCar sample), for the tests
and the benchmark.

Each scan is motion-corrected with the velocity of the previous estimate (the sample has
no odometer), turned into a vehicle-frame grid at the scan's ground-truth time (its middle
beam), located in the growing map by :class:`RSlamCore` with a constant-velocity
prediction, and the relative pose between consecutive estimates is compared with
``gt/radar_odometry.csv``.

It composes two plugins (the radar plugin's Navtech reader and panoramic builder, the
SLAM plugin's matcher), so it lives beside its test, not inside either plugin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from impala_flow.msgs import Grid
from impala_slam.matching import MatchParams
from impala_slam.rslam import RSlamConfig, RSlamCore
from impala_slam.se2 import between, compose, inverse, wrap

__all__ = ["OxfordResult", "register_oxford", "oxford_config"]


def oxford_config(cell_m: float = 0.1) -> RSlamConfig:
    """R-SLAM settings for the Navtech CTS350-X (1.8 degree beam, 4.32 cm bins, 4 Hz)."""
    return RSlamConfig(
        match=MatchParams(search_m=3.0, rot_span_deg=2.0, rot_step_deg=0.25, match_cell_m=4 * cell_m,
                          match_range_m=35.0, contrast_m=2.0, min_score=0.02),
        map_cell_m=cell_m, aperture_deg=1.8, resolution_m=0.5, range_min_m=2.5, range_max_m=60.0,
        intensity="linear",  # the Navtech PNGs already hold power in dB (0.5 dB steps)
    )


@dataclass
class OxfordResult:
    trans_err_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    rot_err_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    ms_per_scan: float = 0.0

    @property
    def mean_trans_err_m(self) -> float:
        return float(np.mean(self.trans_err_m))

    @property
    def mean_rot_err_deg(self) -> float:
        return float(np.mean(self.rot_err_deg))


def _denoise(power: np.ndarray, min_bin: int) -> np.ndarray:
    """Echoes above each beam's noise floor (its median), the first bins (the car) cut."""
    p = np.maximum(power - np.median(power, axis=1, keepdims=True), 0.0)
    p[:, :min_bin] = 0.0
    return p


def scan_grid(path: Path, t_ref_ns: int, speed_mps: float, yaw_rate_radps: float, cell_m: float,
              range_max_m: float) -> Grid:
    """Motion-corrected vehicle-frame grid of one Navtech PNG at ``t_ref_ns`` (CCW azimuths)."""
    from impala_radar.frontend.panoramic import relative_beam_poses, scan_to_grid
    from impala_radar.navtech import NAVTECH_CTS350X, read_navtech_png

    scan = read_navtech_png(path)
    keep = scan.valid
    t = scan.timestamps_ns[keep]
    poses = relative_beam_poses(t, speed_mps, yaw_rate_radps)  # relative to the last beam
    ref = relative_beam_poses(np.array([t_ref_ns, t[-1]], np.int64), speed_mps, yaw_rate_radps)[0]
    inv_ref = inverse(tuple(ref))
    poses = np.array([compose(inv_ref, tuple(p)) for p in poses])
    power = _denoise(scan.power[keep], int(2.0 / NAVTECH_CTS350X.range_per_bin_m))
    # Navtech turns clockwise: reverse the beams so the CCW azimuths increase
    az_ccw = -scan.azimuth_rad[keep][::-1]
    data, (ox, oy) = scan_to_grid(power[::-1], az_ccw, poses[::-1], NAVTECH_CTS350X.range_per_bin_m,
                                  cell_m, range_max_m)
    return Grid(data, cell_m, ox, oy, "vehicle", None)


def register_oxford(folder: str | Path, cell_m: float = 0.1, config: RSlamConfig | None = None,
                    max_scans: int | None = None) -> OxfordResult:
    """Run R-SLAM over the folder's scans; errors of consecutive relative poses vs truth."""
    import time

    from impala_radar.navtech import read_oxford_ground_truth

    folder = Path(folder)
    scans = sorted((int(p.stem), p) for p in (folder / "radar").glob("*.png") if p.stem.isdigit())
    if max_scans:
        scans = scans[:max_scans]
    gt = read_oxford_ground_truth(folder / "gt" / "radar_odometry.csv")
    row_of = {int(s): i for i, s in enumerate(gt.source_radar_t_ns.tolist())}
    cfg = config or oxford_config(cell_m)
    scans = [(s, p) for s, p in scans if s * 1000 in row_of]
    t0 = time.perf_counter()
    # bootstrap: the first scan has no previous velocity; match the first two, then restart
    # with the first scan corrected by that velocity (constant over the two turns)
    core = RSlamCore(cfg)
    for stamp_us, path in scans[:2]:
        t_ref = int(gt.source_t_ns[row_of[stamp_us * 1000]])
        core.step(t_ref, scan_grid(path, t_ref, *core.velocity(), cfg.map_cell_m, cfg.range_max_m))
    v0 = core.velocity()
    core = RSlamCore(cfg)
    est: dict[int, tuple[float, float, float]] = {}
    trans, rot = [], []
    for n, (stamp_us, path) in enumerate(scans):
        r = row_of[stamp_us * 1000]
        t_ref = int(gt.source_t_ns[r])
        v, w = v0 if n < 2 else core.velocity()
        grid = scan_grid(path, t_ref, v, w, cfg.map_cell_m, cfg.range_max_m)
        pose, _, _ = core.step(t_ref, grid)
        est[stamp_us * 1000] = pose
        prev = est.get(int(gt.destination_radar_t_ns[r]))
        if prev is not None:
            rel = between(prev, pose)
            trans.append(math.hypot(rel[0] - gt.x_m[r], rel[1] - gt.y_m[r]))
            rot.append(abs(math.degrees(wrap(rel[2] - gt.yaw_rad[r]))))
    ms = 1e3 * (time.perf_counter() - t0) / max(1, len(est) + 2)
    return OxfordResult(np.array(trans), np.array(rot), ms)
