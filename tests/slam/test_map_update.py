"""Eq. (6) as the seed writes it (``map_update: paper``, N = the number of images merged)
against the default running weighted mean, on a scene with a transient object (issue 9
item 6). Expected values from the formula, alpha(d) = 1 / (1 + d aperture / resolution)."""

import math

import numpy as np
import pytest

from impala_flow.msgs import Grid
from impala_slam.rslam.core import RSlamConfig, RSlamCore
from impala_slam.tilemap import TileMap

CELL = 0.2
HALF_M = 40.0
A_STATIC, A_CAR = 4.0, 10.0
CAR = (25.0, 5.0)  # a parked car glimpsed once, from the first pose, at the edge of the range
WALL = (-8.0, 6.0)  # a wall seen from every pose
POSES = [(0.0, 0.0)] + [(-10.0 - 0.5 * k, 0.0) for k in range(7)]  # the car is > 30 m from these


def _image(pose, with_car: bool) -> Grid:
    """Vehicle-frame panoramic at ``pose`` (heading 0): the objects as 5 x 5 cell blocks."""
    n = int(round(2 * HALF_M / CELL)) + 1
    data = np.zeros((n, n), np.float32)
    for (x, y), a, on in ((WALL, A_STATIC, True), (CAR, A_CAR, with_car)):
        u, v = x - pose[0], y - pose[1]
        if on and math.hypot(u, v) < HALF_M - 1.0:
            i, j = int(round((v + HALF_M) / CELL)), int(round((u + HALF_M) / CELL))
            data[i - 2:i + 3, j - 2:j + 3] = a
    return Grid(data, CELL, -HALF_M, -HALF_M, "vehicle")


def _alpha(xy, pose, cfg: RSlamConfig) -> float:
    d = math.hypot(xy[0] - pose[0], xy[1] - pose[1])
    return 1.0 / (1.0 + d * math.radians(cfg.aperture_deg) / cfg.resolution_m) if d <= cfg.range_max_m else 0.0


@pytest.mark.parametrize("n_images", [3, 8])
def test_paper_normaliser_lets_a_place_seen_often_outweigh_a_transient(n_images):
    poses = POSES[:n_images]
    values = {}
    for mode in ("weighted", "paper"):
        cfg = RSlamConfig(intensity="linear", map_update=mode, range_min_m=0.0, range_max_m=30.0)
        core = RSlamCore(cfg)
        core.map = TileMap(CELL, total_normaliser=mode == "paper")
        for k, pose in enumerate(poses):
            core.update_map(_image(pose, with_car=k == 0), (pose[0], pose[1], 0.0))
        values[mode] = {name: float(core.map.crop(int(round(x / CELL)), int(round(y / CELL)), 1, 1)[0, 0])
                        for name, (x, y) in (("car", CAR), ("wall", WALL))}
    w, p = values["weighted"], values["paper"]
    assert _alpha(CAR, poses[-1], cfg) == 0.0  # the car's place is out of reach after the first pose
    # running weighted mean: every place at the level it was seen at, however often
    assert w["car"] == pytest.approx(A_CAR, rel=1e-5) and w["wall"] == pytest.approx(A_STATIC, rel=1e-5)
    # the paper's 1/N sum alpha A: the wall sums alpha A over every image, the car one term
    assert p["wall"] == pytest.approx(sum(_alpha(WALL, q, cfg) for q in poses) * A_STATIC / n_images, rel=1e-4)
    assert p["car"] == pytest.approx(_alpha(CAR, poses[0], cfg) * A_CAR / n_images, rel=1e-4)
    assert w["car"] > w["wall"] and p["car"] < p["wall"]  # the transient outweighs the wall only in the mean


def test_the_component_takes_map_update():
    from impala_slam.rslam.component import RSlam

    slam = RSlam("slam", map_update="paper")
    slam.start()
    assert slam.core.cfg.map_update == "paper"
    with pytest.raises(ValueError):
        RSlam("slam", map_update="median")


def test_map_bytes_stay_within_the_bound_over_a_long_drive():
    """A 1 km straight drive over a textured world: with ``map_max_mb`` the map never holds
    more than the bound (two float32 layers per tile), the tiles farthest from the vehicle
    are the ones dropped (counted), and since matching only reads the map around the
    vehicle, the poses and the tiles kept are exactly those of the same run unbounded."""
    import cv2

    cell, radius, step_m, bound_mb = 0.5, 30.0, 20.0, 0.25
    rng = np.random.default_rng(3)
    world = cv2.GaussianBlur(rng.random((200, 2200), dtype=np.float32), (0, 0), 2.0) + 1.0  # 100 m x 1.1 km
    y0, x0, h = 100, 80, int(round(radius / cell))  # world cell of (0, 0) m; panoramic half-width in cells
    tile_bytes = 2 * 4 * 32 * 32  # tile_m / cell = 32 cells a side
    limit = int(bound_mb * 2 ** 20)
    runs = {}
    for bound in (bound_mb, 0.0):
        cfg = RSlamConfig(intensity="linear", map_cell_m=cell, tile_m=16.0, range_min_m=0.0, range_max_m=radius,
                          map_max_mb=bound)
        cfg.match.match_cell_m, cfg.match.match_range_m, cfg.match.contrast_m = 1.0, 25.0, 3.0
        core = RSlamCore(cfg)
        poses, created = [], set()
        for k in range(51):
            c = x0 + int(round(step_m * k / cell))
            g = Grid(world[y0 - h: y0 + h + 1, c - h: c + h + 1].copy(), cell, -radius, -radius, "vehicle")
            poses.append(core.step(k * 250_000_000, g, (step_m * k, 0.0, 0.0))[0])
            created |= set(core.map.count)
            if bound:
                assert core.map.nbytes <= limit
        runs[bound] = core, poses, created
    (bounded, poses, created), (unbounded, poses_full, _) = runs[bound_mb], runs[0.0]
    tm, full = bounded.map, unbounded.map
    assert tm.nbytes == tm.n_tiles * tile_bytes == (limit // tile_bytes) * tile_bytes
    assert full.nbytes > 5 * limit and full.dropped_tiles == 0
    assert tm.dropped_tiles == len(created) - tm.n_tiles == full.n_tiles - tm.n_tiles
    assert poses == poses_full
    for key in tm.count:
        assert np.array_equal(tm.weighted_sum[key], full.weighted_sum[key])
        assert np.array_equal(tm.count[key], full.count[key])
    x_end = poses[-1][0]
    dist = {key: math.hypot((key[0] * 32 + 15.5) * cell - x_end, (key[1] * 32 + 15.5) * cell) for key in full.count}
    # the near tiles are kept (what matching reads), the far ones behind dropped
    assert {key for key, d in dist.items() if d < 50.0} <= set(tm.count)
    assert not {key for key, d in dist.items() if d > 110.0} & set(tm.count)
