"""PanoramicBuilder: motion-corrected Cartesian panoramic images (seed 1 §4.1.1)."""

import numpy as np

from impala_flow.msgs import Grid
from impala_flow.testing import CollectingSink, ScriptedSource, run_components
from impala_msgs import RadarScan, Speed, YawRate
from impala_radar.panoramic.component import PanoramicBuilder
from impala_radar.panoramic.core import relative_beam_poses, relative_to, scan_to_grid
from impala_radar.simulator.core import simulate
from impala_radar.simulator.presets import IMPALA
from impala_radar.simulator.spectra import RadarParams
from impala_radar.simulator.vehicle import Trajectory
from impala_radar.simulator.world import WorldBuilder

V_MPS = 5.0
CELL_M = 0.2
POINTS = np.array([[30.0, 20.0], [-25.0, -15.0], [5.0, 40.0], [40.0, -30.0]])


def _mission(yaw_rate=0.0):
    rng = np.random.default_rng(5)
    b = WorldBuilder(rng)
    b.points(POINTS, 1.3, 10.0, "point")
    world = b.build()
    if yaw_rate:
        r = V_MPS / yaw_rate
        a = np.linspace(-0.5, 1.0, 40)
        traj = Trajectory.from_waypoints(np.column_stack([r * np.sin(a), r * (1 - np.cos(a))]), V_MPS,
                                         rest_at_ends=False, max_curvature_1pm=1.0 / (0.9 * r))
    else:
        traj = Trajectory.from_waypoints(np.array([[-20.0, 0.0], [200.0, 0.0]]), V_MPS, rest_at_ends=False)
    ev = list(simulate(world, traj, IMPALA, rng, start_t_ns=traj.start_ns + 1_000_000_000,
                       duration_ns=1_000_000_000, params=RadarParams(thermal_noise=False)))
    return traj, [e for e in ev if e[1] == "beams"]


def _peak_offsets_cells(grid, origin, truth_xy, half=40):
    """Offset (x, y) in cells of each echo from its true place: centroid of the cells above
    half the maximum within 6 cells of the maximum (the polar image samples 1 deg x 0.375 m,
    so the maximum cell alone is quantised to ~1 cell)."""
    out = []
    for tx, ty in truth_xy:
        j, i = int(round((tx - origin[0]) / CELL_M)), int(round((ty - origin[1]) / CELL_M))
        sub = grid[i - half:i + half + 1, j - half:j + half + 1].astype(float)
        ki, kj = np.unravel_index(np.argmax(sub), sub.shape)
        win = sub[ki - 6:ki + 7, kj - 6:kj + 7]
        w = np.where(win >= 0.5 * win.max(), win, 0.0)
        yy, xx = np.mgrid[-6:7, -6:7]
        out.append((kj - half + (w * xx).sum() / w.sum(), ki - half + (w * yy).sum() / w.sum()))
    return np.array(out)


def test_relative_beam_poses_constant_velocity():
    t = np.array([0, 500_000_000, 1_000_000_000])
    p = relative_beam_poses(t, 4.0, 0.0)
    assert np.allclose(p, [[-4.0, 0, 0], [-2.0, 0, 0], [0, 0, 0]])
    p = relative_beam_poses(t, 2.0, np.pi / 2)  # quarter circle of radius 4/pi in 1 s
    r = 4.0 / np.pi
    assert np.allclose(p[0], [-r, r, -np.pi / 2])


def test_static_point_lands_within_two_cells_and_smears_without_correction():
    traj, beams = _mission()
    t_ns = np.array([t for t, _, _ in beams], np.int64)
    az = np.array([b.azimuth_rad for _, _, b in beams])
    power = np.stack([b.up for _, _, b in beams])
    ref = traj.pose(t_ns[-1])
    truth = relative_to(np.column_stack([POINTS, np.zeros(len(POINTS))]), ref)[:, :2]
    # the up ramp alone carries the static Doppler f_d: compare with the Doppler-compensated image
    from impala_radar.panoramic.core import doppler_compensated_power

    power = doppler_compensated_power(power, np.stack([b.down for _, _, b in beams]), az, V_MPS, IMPALA)
    g, o = scan_to_grid(power, az, relative_beam_poses(t_ns, V_MPS, 0.0), IMPALA.range_per_bin_m, CELL_M, 100.0)
    err = np.hypot(*_peak_offsets_cells(g, o, truth).T)
    g0, o0 = scan_to_grid(power, az, np.zeros((len(t_ns), 3)), IMPALA.range_per_bin_m, CELL_M, 100.0)
    smear = _peak_offsets_cells(g0, o0, truth, half=60)
    # analytic displacement: the vehicle drove v (t_ref - t_seen) since the beam saw the point
    bearing = np.mod(np.arctan2(*(POINTS - traj.pose(t_ns[0])[:2]).T[::-1]), 2 * np.pi)
    t_seen = t_ns[np.argmin(np.abs(az[:, None] - bearing[None, :]), axis=0)]
    expected_cells = V_MPS * (t_ns[-1] - t_seen) * 1e-9 / CELL_M
    print(f"\ncorrected peak error (cells): {np.round(err, 1)}; uncorrected x offsets {np.round(smear[:, 0], 1)} "
          f"vs v*dt = {np.round(expected_cells, 1)} cells")
    assert err.max() <= 2.0
    assert np.all(np.abs(smear[:, 0] - expected_cells) <= 2.0)  # displaced along x by v dt
    assert smear[:, 0].max() >= 15  # up to v x 1 s = 25 cells for a point seen first


def test_component_grid_contract_with_odometer_and_gyro():
    yaw = 0.2
    traj, beams = _mission(yaw_rate=yaw)
    t0, t1 = beams[0][0], beams[-1][0]
    span = (t0 - 40_000_000, t1 + 40_000_000)
    odo = [(t, "odo", Speed(float(traj.velocity(t)[0]))) for t in range(*span, 20_000_000)]
    gyr = [(t, "gyro", YawRate(float(traj.velocity(t)[1]))) for t in range(*span, 10_000_000)]
    samples = sorted([(t, "beams", b) for t, _, b in beams] + odo + gyr, key=lambda s: s[0])
    images, scans = CollectingSink("img"), CollectingSink("scan")
    run_components(ScriptedSource("src", samples), PanoramicBuilder("pano"), images, scans,
                   connections=["src.beams -> pano.beams", "src.odo -> pano.odometer", "src.gyro -> pano.gyro",
                                "pano.image -> img.x", "pano.scan -> scan.x"])
    assert images.times() == [t1] and scans.times() == [t1]
    g: Grid = images.values()[0]
    s: RadarScan = scans.values()[0]
    assert s.power.shape == (360, IMPALA.n_bins) and s.t_ns[-1] == t1
    assert g.frame == "vehicle" and g.cell_m == CELL_M and g.data.dtype == np.float32
    n_half = int(np.ceil(IMPALA.range_max_m / CELL_M))
    assert g.data.shape == (2 * n_half + 1,) * 2 and g.origin_x_m == g.origin_y_m == -n_half * CELL_M
    # dead-reckoned pose at t_ref: the odom frame starts at the first beam's pose
    truth_rel = relative_to(traj.pose(np.array([t1])), traj.pose(t0))[0]
    assert g.pose.frame == "odom"
    assert np.allclose([g.pose.x_m, g.pose.y_m, g.pose.theta_rad], truth_rel, atol=0.02)
    truth = relative_to(np.column_stack([POINTS, np.zeros(len(POINTS))]), traj.pose(t1))[:, :2]
    err = np.hypot(*_peak_offsets_cells(g.data, (g.origin_x_m, g.origin_y_m), truth).T)
    assert err.max() <= 2.0


def test_ground_echoes_land_at_their_ground_range():
    """The spectra measure slant range sqrt(r^2 + h^2) to a ground echo (radar 1.3 m high);
    the grid is a ground plane: with the ground-range projection each echo lands at its
    ground range r (analytic), without it sqrt(r^2 + h^2) - r too far (17 cm at 5 m, a
    radial stretch of the near image that biased R-SLAM's along-track motion by 1.3 cm
    per turn on Beynes)."""
    ground = np.array([[5.0, 0.0], [0.0, 8.0], [-12.0, 0.0], [0.0, -20.0], [28.0, 28.0]])
    rng = np.random.default_rng(3)
    b = WorldBuilder(rng)
    b.points(ground, 0.0, 10.0, "point")  # on the ground, the radar IMPALA.height_m above
    traj = Trajectory.stationary(0.0, 0.0, 0.0, 2.0)
    beams = [e[2] for e in simulate(b.build(), traj, IMPALA, rng, duration_ns=1_000_000_000,
                                    params=RadarParams(thermal_noise=False)) if e[1] == "beams"]
    az = np.array([bm.azimuth_rad for bm in beams])
    power = np.stack([bm.up for bm in beams])
    r_true = np.hypot(*ground.T)
    cell = 0.05
    found = {}
    for h in (IMPALA.height_m, 0.0):
        g, o = scan_to_grid(power, az, np.zeros((len(az), 3)), IMPALA.range_per_bin_m, cell, 45.0, height_m=h)
        off = []
        for (x, y), r in zip(ground, r_true, strict=True):
            j, i = int(round((x - o[0]) / cell)), int(round((y - o[1]) / cell))
            sub = g[i - 30:i + 31, j - 30:j + 31].astype(float)
            w = np.where(sub >= 0.5 * sub.max(), sub, 0.0)
            yy, xx = np.mgrid[-30:31, -30:31]
            px, py = x + cell * (w * xx).sum() / w.sum(), y + cell * (w * yy).sum() / w.sum()
            off.append(np.hypot(px, py) - r)
        found[h] = np.array(off)
    slant_excess = np.hypot(r_true, IMPALA.height_m) - r_true
    print(f"\nradial offsets (m): ground range {np.round(found[IMPALA.height_m], 3)}, slant "
          f"{np.round(found[0.0], 3)} vs analytic excess {np.round(slant_excess, 3)}")
    # 1.5 cm of the 5 m echo's offset is the centroid of its 1 deg x 0.375 m polar samples
    assert np.all(np.abs(found[IMPALA.height_m]) < 0.03)
    assert np.allclose(found[0.0], slant_excess, atol=0.03)


def _grid_numpy(power, az, poses, bin_m, cell_m, range_max_m, height_m, offset_m, range_min_m):
    """scan_to_grid's formula written with numpy and cv2 alone, cell by cell over the square
    (the compiled loops must give the same float32 grid bit for bit)."""
    import cv2

    order = np.argsort(np.mod(az, 2 * np.pi), kind="stable")
    a = np.mod(az, 2 * np.pi)[order]
    spacing = float(np.median(np.diff(a)))
    n_half = int(np.ceil(range_max_m / cell_m))
    c = (np.arange(-n_half, n_half + 1) * cell_m).astype(np.float32)
    x, y = np.meshgrid(c, c)
    r_cell, bearing = cv2.cartToPolar(x, y)

    def rows_of(b):
        return np.mod(b - np.float32(a[0]), np.float32(2 * np.pi)) * np.float32(1 / spacing) + np.float32(1)

    i0 = order[np.clip(np.rint(rows_of(bearing)).astype(np.intp) - 1, -1, len(a)) % len(a)]
    p = poses.astype(np.float32)
    ct, st = np.cos(poses[:, 2]).astype(np.float32), np.sin(poses[:, 2]).astype(np.float32)
    dx, dy = x - p[i0, 0], y - p[i0, 1]
    r, b = cv2.cartToPolar(ct[i0] * dx + st[i0] * dy, ct[i0] * dy - st[i0] * dx)
    r_read = cv2.magnitude(r, np.full_like(r, np.float32(height_m)))
    map_x = (r_read - np.float32(offset_m)) * np.float32(1 / bin_m)
    src = np.asarray(power, np.float32)[order]
    grid = cv2.remap(np.concatenate([src[-1:], src, src[:1]]), map_x, rows_of(b), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    grid[(r_cell > range_max_m) | (r < range_min_m)] = 0.0
    return grid


def test_grid_is_the_numpy_formula_bit_for_bit():
    """A clockwise turn of 400 beams wrapping through 0, moving and turning: the compiled
    per-cell loops give the numpy formula's float32 grid exactly (twice: the cached geometry)."""
    rng = np.random.default_rng(11)
    n = 400
    az = np.mod(-0.04 - np.arange(n) * 2 * np.pi / n, 2 * np.pi)
    t_ns = np.arange(n, dtype=np.int64) * 625_000
    poses = relative_beam_poses(t_ns, 9.0, 0.3)
    power = rng.exponential(1.0, (n, 200)).astype(np.float32)
    want = _grid_numpy(power, az, poses, 0.17361, 0.2, 30.0, 1.3, 0.0868, 2.0)
    for _ in range(2):
        got, _ = scan_to_grid(power, az, poses, 0.17361, 0.2, 30.0, 1.3, 0.0868, 2.0)
        assert np.array_equal(got.view(np.int32), want.view(np.int32))


def test_doppler_compensation_is_the_numpy_formula_bit_for_bit():
    """The compiled Doppler loop gives 0.5 (up shifted by -f_d + down shifted by +f_d), the
    float32 numpy formula, exactly; a shift of whole bins moves the spectra by that many bins."""
    from impala_msgs import SPEED_OF_LIGHT_MPS
    from impala_radar.panoramic.core import _shift_rows, doppler_compensated_power

    rng = np.random.default_rng(2)
    az = np.arange(360) * np.pi / 180.0
    up = rng.exponential(1.0, (360, 288)).astype(np.float32)
    down = rng.exponential(1.0, (360, 288)).astype(np.float32)
    for v in (0.0, 4.2, -13.0, 60.0):
        shift = 2.0 * IMPALA.f0_hz * (-v * np.cos(az)) / SPEED_OF_LIGHT_MPS / IMPALA.bin_hz
        want = 0.5 * (_shift_rows(up, shift) + _shift_rows(down, -shift))
        got = doppler_compensated_power(up, down, az, v, IMPALA)
        assert got.dtype == np.float32 and np.array_equal(got.view(np.int32), want.view(np.int32))
    k = np.round(2.0 * IMPALA.f0_hz * 10.0 / SPEED_OF_LIGHT_MPS / IMPALA.bin_hz)  # whole bins at 180 deg
    v = k * IMPALA.bin_hz * SPEED_OF_LIGHT_MPS / (2.0 * IMPALA.f0_hz)
    got = doppler_compensated_power(up, down, az, v, IMPALA)
    kk = int(k)
    np.testing.assert_allclose(got[180, kk:-kk], 0.5 * (up[180, 2 * kk:] + down[180, :-2 * kk]), rtol=1e-6)


def test_compiled_polar_and_bilinear_read_are_opencvs_bit_for_bit():
    """The compiled loops against OpenCV itself: ranges and bearings as cv2.cartToPolar gives
    them (cells on the axes and diagonals included), and the bilinear read as cv2.remap
    (INTER_LINEAR, constant 0 border) gives it, for reads inside, across the border and
    outside the polar image."""
    import cv2

    from impala_radar.panoramic import _jit
    from impala_radar.panoramic.core import _ATAN_P, _TWO_PI_F32

    rng = np.random.default_rng(3)
    n = 201
    c = (np.arange(-(n // 2), n // 2 + 1) * 0.3).astype(np.float32)
    spans = np.column_stack([np.zeros(n, np.int64), np.full(n, n, np.int64)])
    n_beams = 64
    i0 = rng.integers(0, n_beams, (n, n)).astype(np.uint16)
    px, py = (rng.normal(0.0, 1.5, n_beams).astype(np.float32) for _ in range(2))
    px[:8] = py[:8] = 0.0  # cells read by these beams fall on the axes and diagonals of their frame
    th = rng.uniform(-0.2, 0.2, n_beams)
    th[:8] = 0.0
    ct, st = np.cos(th).astype(np.float32), np.sin(th).astype(np.float32)
    r, bearing = np.empty(n * n, np.float32), np.empty(n * n, np.float32)
    _jit.polar_cells(c, spans, i0, px, py, ct, st, _ATAN_P, False, np.float32(0), np.float32(1), _TWO_PI_F32,
                     0, n, 0, r, bearing)
    x, y = np.meshgrid(c, c)
    k = i0.astype(np.intp)
    dx, dy = x - px[k], y - py[k]
    want_r, want_b = cv2.cartToPolar(ct[k] * dx + st[k] * dy, ct[k] * dy - st[k] * dx)
    assert np.array_equal(r.view(np.int32), want_r.ravel().view(np.int32))
    assert np.array_equal(bearing.view(np.int32), want_b.ravel().view(np.int32))

    power = rng.exponential(1.0, (n_beams, 40)).astype(np.float32)
    order = rng.permutation(n_beams)
    rows = np.concatenate([power[order][-1:], power[order], power[order][:1]])
    bin_m, offset_m = np.float32(0.25), np.float32(0.1)
    map_x = rng.uniform(-3.0, 43.0, (n, n)).astype(np.float32)
    map_y = rng.uniform(-2.5, n_beams + 3.5, (n, n)).astype(np.float32)
    map_x[::7, ::5] = np.floor(map_x[::7, ::5])  # whole bins and rows: weights of exactly 0
    map_y[::3, ::11] = np.float32(-1.0)
    r_read = (map_x / np.float32(1.0 / bin_m) + offset_m).astype(np.float32)
    map_x = (r_read - offset_m) * np.float32(1.0 / bin_m)  # the bins the loop computes from r_read
    near = rng.uniform(size=(n, n)) < 0.05
    r_cell = np.where(near, np.float32(0.5), np.float32(10.0)).astype(np.float32)
    want = cv2.remap(rows, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    want[near] = 0.0
    got = np.zeros((n, n), np.float32)
    _jit.read_cells(_jit.pad_polar(power, order), n_beams, 40, spans, 0, n, 0, r_read.ravel(), r_cell.ravel(),
                    map_y.ravel(), offset_m, np.float32(1.0 / bin_m), np.float32(1.0), got)
    assert np.array_equal(got.view(np.int32), want.view(np.int32))
    assert 0 < np.count_nonzero(got) < got.size


def test_grid_of_a_partial_turn_is_the_formula_of_its_beams():
    """A partial turn with missing beams (a non-uniform azimuth table) and no motion: the
    packed loops over the disk give what remap gives over the square with the table's rows."""
    import cv2

    from impala_radar.panoramic.core import AzimuthTable, grid_geometry

    rng = np.random.default_rng(4)
    az = np.concatenate([np.arange(0, 150), np.arange(170, 300), np.arange(301, 380)]) * 2 * np.pi / 400
    power = rng.exponential(1.0, (len(az), 120)).astype(np.float32)
    got, _ = scan_to_grid(power, az, np.zeros((len(az), 3)), 0.25, 0.25, 25.0, 1.1, 0.05, 1.0)
    table = AzimuthTable(az)
    assert not table.uniform
    x, y, r, bearing = grid_geometry(100, 0.25)
    r_read = cv2.magnitude(r, np.full_like(r, np.float32(1.1)))
    map_x = (r_read - np.float32(0.05)) * np.float32(1.0 / 0.25)
    want = cv2.remap(table.rows(power), map_x, table.row_of(bearing), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    want[(r > np.float32(25.0)) | (r < np.float32(1.0))] = 0.0
    assert np.array_equal(got.view(np.int32), want.view(np.int32))
