"""R-SLAM on several threads (``threads``) and its compiled map merge give the same bits as on
one thread and as the numpy formulation they replace."""

import math

import cv2
import numpy as np
import pytest

from impala_slam.rslam._jit import contrast_box, db_tail, mean_tile, merge_tile
from impala_slam.rslam.component import RSlam
from impala_slam.rslam.core import RSlamConfig, RSlamCore
from impala_slam.synthetic import SyntheticWorld
from impala_slam.tilemap import TileMap

cv2.setNumThreads(1)


@pytest.mark.parametrize("weighted", [True, False])
def test_the_compiled_merge_equals_the_masked_numpy_add(weighted):
    """Eq. (6)'s accumulation as R-SLAM wrote it before (alpha zeroed where the amplitude is
    NaN, alpha A, TileMap.add's masked add) against TileMap.add_with + merge_tile: the same
    tiles, bit for bit, over a window crossing tile borders, with NaN and alpha = 0 cells
    and a tile the window only touches where nothing is covered (not created by either)."""
    rng = np.random.default_rng(5)
    n = 150
    amp = (rng.random((n, n)) * 40.0).astype(np.float32)
    amp[:, :30] = np.nan
    amp[rng.random((n, n)) < 0.05] = np.nan
    alpha = rng.random((n, n)).astype(np.float32)
    alpha[rng.random((n, n)) < 0.2] = 0.0
    alpha[-20:] = 0.0  # the window's last rows cover nothing
    old, new = TileMap(0.2, tile_m=8.0), TileMap(0.2, tile_m=8.0)  # 40-cell tiles
    for k, (ix0, iy0) in enumerate([(-37, -15), (-20, -17), (-37, -15)]):
        a = alpha.copy()
        m = amp.copy()
        np.copyto(a, np.float32(0.0), where=np.isnan(m))
        w = np.multiply(a, m, out=m)
        old.add(ix0, iy0 + k, w, a if weighted else a > 0)
        new.add_with(ix0, iy0 + k, n, n, lambda win, ws, cnt: merge_tile(amp[win], alpha[win], ws, cnt, weighted))
    assert sorted(old.count) == sorted(new.count)
    assert len(new.count) == 20 and not any(ty == 3 for _, ty in new.count)  # rows 120-: alpha = 0 there
    for key in old.count:
        assert np.array_equal(old.weighted_sum[key], new.weighted_sum[key])
        assert np.array_equal(old.count[key], new.count[key])


def test_the_compiled_read_equals_crop_with_support():
    """The weighted mean and support read through TileMap.crop_with + mean_tile against
    crop_with_support's masked division, bit for bit, over a window reaching unmapped tiles."""
    rng = np.random.default_rng(6)
    tm = TileMap(0.2, tile_m=8.0)
    n = 130
    alpha = rng.random((n, n)).astype(np.float32)
    alpha[rng.random((n, n)) < 0.3] = 0.0
    tm.add(-20, -30, (rng.random((n, n)) * 30.0).astype(np.float32) * alpha, alpha)
    for window in [(-50, -60, 200, 190), (-5, 7, 33, 41)]:
        old, new = tm.crop_with_support(*window), tm.crop_with(*window, mean_tile)
        assert np.array_equal(old[0], new[0]) and np.array_equal(old[1], new[1])
        assert 0 < new[1].sum() < new[1].size or window[2] == 33  # mapped and unmapped cells in the first


@pytest.mark.parametrize("k", [3, 5, 9, 11, 15])
def test_the_compiled_contrast_equals_cv2_blur_and_the_numpy_tail(k):
    """contrast()'s compiled pass against what it replaces, bit for bit: cv2.blur (BORDER_CONSTANT)
    of img * support and of support, then the numpy divide (where weight > 1e-3), subtract and
    multiply; on a view and a contiguous image, with a 0/1 support, an empty one and a fractional
    one whose box means fall at and around 1e-3 (NumPy 2 compares a float32 array with a Python
    float in float32)."""
    rng = np.random.default_rng(8 + k)
    big = (rng.normal(size=(90, 100)) * 20.0).astype(np.float32)
    img = big[7:80, 3:91]  # a view, rows not contiguous
    binary = (rng.random(img.shape) > 0.3).astype(np.float32)
    fractional = (rng.random(img.shape) * np.float32(2e-3)).astype(np.float32)
    fractional[::5] = np.float32(1e-3)
    fractional[:, ::7] = 0.0
    near = 0
    cases = [(img, s) for s in (binary, fractional, np.zeros_like(binary))]
    cases.append((np.ascontiguousarray(img), binary))  # the C-contiguous build of the kernel too
    for img, support in cases:
        mean = cv2.blur(img * support, (k, k), borderType=cv2.BORDER_CONSTANT)
        weight = cv2.blur(support, (k, k), borderType=cv2.BORDER_CONSTANT)
        near += int(((weight > 5e-4) & (weight < 2e-3)).sum())
        old = mean.copy()
        np.divide(old, weight, out=old, where=weight > 1e-3)
        np.subtract(img, old, out=old)
        np.multiply(old, support, out=old)
        new = np.empty(img.shape, np.float32)
        contrast_box(img, support, k, new)
        assert np.array_equal(old, new) and np.array_equal(np.signbit(old), np.signbit(new))
    assert near > 100  # the threshold's neighbourhood was exercised


def test_the_compiled_db_tail_equals_numpy():
    """RSlamCore.amplitude's last step against the numpy subtract, multiply and masked copy it
    replaces, bit for bit: unobserved (0), negative and NaN cells read 0, on a view too."""
    rng = np.random.default_rng(9)
    p = (rng.random((70, 90)) * 1e-3).astype(np.float32)
    p[rng.random(p.shape) < 0.2] = 0.0
    p[::7, ::5] = np.nan
    p[3, :10] = -1.0
    floor = 2e-5
    for q in (p, p[5:60, 7:80]):
        a = np.maximum(q, np.float32(floor))
        cv2.log(a, dst=a)  # ln max(p, floor), as RSlamCore.amplitude takes it
        old = a.copy()
        old -= np.float32(math.log(floor))
        old *= np.float32(10.0 / math.log(10.0))
        np.copyto(old, np.float32(0.0), where=np.logical_not(np.greater(q, 0.0)))
        new = a.copy()
        db_tail(new, q, np.float32(math.log(floor)), np.float32(10.0 / math.log(10.0)))
        assert np.array_equal(old, new) and np.array_equal(np.signbit(old), np.signbit(new))
        assert (new == 0).sum() > 0.2 * new.size and np.isfinite(new).all()


def _run(threads: int, world: SyntheticWorld) -> tuple[list, RSlamCore]:
    """A 14-turn drive with a bend and a missing second (the widened search), no odometry."""
    rng = np.random.default_rng(11)
    core = RSlamCore(RSlamConfig(range_max_m=45.0, db_floor_quantile=0.5, threads=threads))
    core.cfg.match.match_range_m = 40.0
    out, t, pose = [], 0, (0.0, 0.0, 0.0)
    for k in range(14):
        t += 250_000_000 if k != 9 else 1_250_000_000
        dt = 0.25 if k != 9 else 1.25
        pose = (pose[0] + 6.0 * dt * math.cos(pose[2]), pose[1] + 6.0 * dt * math.sin(pose[2]), pose[2] + 0.1 * dt)
        p, cov, ok = core.step(t, world.render(pose, rng, radius_m=45.0))
        out.append((p, cov.copy(), ok))
    core.close()
    return out, core


def test_threads_give_the_same_poses_and_map_bit_for_bit():
    world = SyntheticWorld.random(np.random.default_rng(7), (-60, 140), (-80, 120), 0.03, 3)
    (one, c1), (two, c2), (three, c3) = (_run(n, world) for n in (1, 2, 3))
    assert all(ok for _, _, ok in one)  # a sane run: every turn matched, the one after the gap too
    for other, core in ((two, c2), (three, c3)):
        for (p, cov, ok), (q, cov2, ok2) in zip(one, other, strict=True):
            assert p == q and ok == ok2 and np.array_equal(cov, cov2)
        assert sorted(core.map.count) == sorted(c1.map.count)
        for key in c1.map.count:
            assert np.array_equal(core.map.weighted_sum[key], c1.map.weighted_sum[key])
            assert np.array_equal(core.map.count[key], c1.map.count[key])
    # the split counts the helper's CPU: every stage was timed
    assert set(c2.split) == {"amplitude", "prepare", "coarse", "fine", "update"}
    assert all(v > 0 for v in c2.split.values())


def test_the_climbed_coarse_rotations_give_the_whole_span_poses(monkeypatch):
    """The coarse level climbs from the expected rotation (the last innovation) instead of
    correlating every rotation of the span: on a drive whose rotation peaks have one summit it
    finds the same rotations, so the same poses bit for bit, with fewer correlations (the
    whole span forced by starting the climb with more rotations than the span has)."""
    from impala_slam.rslam import matching

    world = SyntheticWorld.random(np.random.default_rng(7), (-60, 140), (-80, 120), 0.03, 3)
    count = {"n": 0}
    call = matching._Correlator.__call__

    def counted(self, *args):
        count["n"] += 1
        return call(self, *args)

    monkeypatch.setattr(matching._Correlator, "__call__", counted)
    climbed, _ = _run(1, world)
    n_climbed, count["n"] = count["n"], 0
    monkeypatch.setattr(matching, "_CLIMB_START", 10 ** 6)
    whole, _ = _run(1, world)
    assert all(ok for _, _, ok in climbed)
    for (p, cov, ok), (q, cov2, ok2) in zip(climbed, whole, strict=True):
        assert p == q and ok == ok2 and np.array_equal(cov, cov2)
    assert n_climbed < count["n"]  # fewer correlations for the same poses


def test_the_component_bounds_threads_and_ends_its_helpers():
    with pytest.raises(ValueError):
        RSlam("slam", threads=0)
    with pytest.raises(ValueError):
        RSlam("slam", threads=9)
    slam = RSlam("slam")
    slam.start()
    assert slam.threads == 2 and slam.core._workers == 1
    slam.stop()
    assert slam.core._pool is None and slam.core._workers == 0
