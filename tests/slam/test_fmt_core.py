"""The FMT's shortcuts give the numbers of the plain computations they replace (issue 26).

Each shortcut of impala_slam.fmt.core (the translation's FFTs restricted to the columns its
low-pass keeps, |fft2| rebuilt from rfft2 within the band's radius, the SNR without a mask,
the 2 x 2 mean without numpy's strided reduction) is checked against the computation as
written before: whole spectra with scipy.fft.rfft2 / fft2, numpy's mean and std over a
boolean mask. Bit for bit, except the translation's surface: numpy's complex64 product of the
same two numbers can differ in the last bit with the arrays' sizes (seen on 256 x 64 against
256 x 129 spectra; on the 512 x 512 RADIATE turns every registration came out bit-identical),
so it is compared to float32 rounding and the peak it gives to 1e-4 cell. Images: a synthetic
world rendered at two poses (impala_slam.synthetic) and seeded noise.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
import scipy.fft

from impala_flow.msgs import Grid
from impala_slam.fmt import core, correlation, spectra, transforms
from impala_slam.fmt.core import FmtParams, prepare, register
from impala_slam.synthetic import SyntheticWorld

cv2.setNumThreads(1)
P = FmtParams(cell_m=0.2, size=256, range_min_m=2.5, range_max_m=25.0, taper_m=4.0, min_wavelength_m=0.8)


def _images(p: FmtParams = P) -> tuple[core.FmtImage, core.FmtImage]:
    rng = np.random.default_rng(3)
    world = SyntheticWorld.random(rng, (-60, 60), (-60, 60), density_per_m2=0.02, n_clusters=12)
    a = world.render((0.0, 0.0, 0.0), rng, cell_m=0.1, radius_m=26.0)
    b = world.render((1.3, -0.4, math.radians(4.0)), rng, cell_m=0.1, radius_m=26.0)
    return prepare(a, p), prepare(b, p)


def _plain_surface(a: np.ndarray, b: np.ndarray, weight: np.ndarray | None) -> np.ndarray:
    fa, fb = scipy.fft.rfft2(a, workers=1), scipy.fft.rfft2(b, workers=1)
    cross = fb * np.conj(fa)
    cross /= np.maximum(np.abs(cross), 1e-12 * max(float(np.abs(cross).max()), 1e-30))
    if weight is not None:
        cross *= weight
    return scipy.fft.irfft2(cross, s=a.shape, workers=1)


@pytest.mark.parametrize("min_wavelength_m", [0.8, 1.5, 0.0])
def test_translation_surface_is_the_whole_spectrum_one(min_wavelength_m):
    a, b = _images()
    hann = transforms.hann_window(a.image.shape)
    wa, wb = a.image * hann, core._derotate(b.image, math.radians(-4.0)) * hann
    weight = spectra.low_pass(wa.shape[0], P.cell_m, min_wavelength_m)
    cols, w = correlation.spectrum_columns(wa.shape, weight)
    if min_wavelength_m == 0.8:
        assert cols == wa.shape[1] // 4  # cut-off at 0.25 cycles / cell (weight 0 there): columns 0 to n / 4 - 1
    surface = correlation._correlate(transforms.rfft2_first(wa, cols), transforms.rfft2_first(wb, cols), w, wa.shape)
    plain = _plain_surface(wa, wb, weight)
    np.testing.assert_allclose(surface, plain, rtol=0, atol=1e-6 * float(np.abs(plain).max()))
    got, want = correlation.surface_peak(surface), correlation.surface_peak(plain)
    np.testing.assert_allclose(got[:2], want[:2], atol=1e-4)
    assert got[2] == pytest.approx(want[2], rel=1e-4)


@pytest.mark.parametrize("min_wavelength_m, coarse", [(0.8, True), (1.5, True), (0.6, False), (0.0, False)])
@pytest.mark.parametrize("theta_deg", [-4.0, 3.0, 60.0])
def test_coarse_grid_peak_is_the_whole_surface_one(min_wavelength_m, coarse, theta_deg):
    # a low-pass 0 beyond 1/4 cycle per cell (min_wavelength_m >= 4 cells): the peak, its Hessian and
    # SNR from the n/2 x n/2 grid are those of the plain n x n surface (numpy's irfft2 of the whole spectrum)
    a, b = _images()
    hann = transforms.hann_window(a.image.shape)
    wa, wb = a.image * hann, core._derotate(b.image, math.radians(theta_deg)) * hann
    n = wa.shape[0]
    weight = spectra.low_pass(n, P.cell_m, min_wavelength_m)
    cols, w = correlation.spectrum_columns(wa.shape, weight, True)
    rows = correlation.coarse_rows(n, weight, cols)
    assert (rows is not None) == coarse
    if not coarse:
        return
    fa, fb = transforms.rfft2_first(wa, cols), transforms.rfft2_first(wb, cols)
    got = correlation.coarse_peak(fa[rows], fb[rows], w[rows], n)
    want = correlation.surface_peak(_plain_surface(wa, wb, weight))
    np.testing.assert_allclose(got[:2], want[:2], atol=1e-4)
    assert got[2] == pytest.approx(want[2], rel=1e-4)
    np.testing.assert_allclose(got[3], want[3], rtol=1e-4, atol=1e-6)


def test_polar_spectrum_is_the_whole_spectrum_one():
    a, _ = _images()
    img, n = a.image, a.image.shape[0]
    windowed = img * transforms.hann_window(img.shape)
    spec = np.abs(scipy.fft.fftshift(scipy.fft.fft2(windowed, workers=1))).astype(np.float32)
    spec *= spectra._high_pass(n)
    polar = cv2.warpPolar(spec, (n // 2, P.angles), (float(n // 2), float(n // 2)), n // 2,
                          cv2.INTER_LINEAR + cv2.WARP_FILL_OUTLIERS + cv2.WARP_POLAR_LINEAR)
    band = polar[:, int(P.band[0] * n):int(P.band[1] * n)]
    want = (band / float(band.std())).astype(np.float32)
    # to float32 rounding: the spectrum is OpenCV's transform of the rows then scipy.fft's of the columns
    alone = core.polar_spectrum(img, P)
    np.testing.assert_allclose(alone, want, rtol=1e-4, atol=1e-5 * float(np.abs(want).max()))
    from impala_slam.fmt.parallel import TaskPool

    pool = TaskPool(2)  # the resampling by halves of the angles on its threads: the same numbers
    try:
        np.testing.assert_array_equal(core.polar_spectrum(img, P, pool=pool), alone)
    finally:
        pool.close()


@pytest.mark.parametrize("iy, ix", [(40, 70), (0, 127), (125, 2)])
def test_snr_is_the_masked_mean_and_std(iy, ix):
    c = np.random.default_rng(iy + ix).normal(size=(128, 128)).astype(np.float32)
    c[iy, ix] = 30.0
    mask = np.ones(c.shape, bool)
    mask[np.ix_(np.arange(iy - 3, iy + 4) % 128, np.arange(ix - 3, ix + 4) % 128)] = False
    rest = c[mask]
    assert correlation.masked_snr(c, iy, ix) == float((c[iy, ix] - rest.mean()) / float(rest.std()))


def test_two_by_two_mean_is_numpys():
    data = np.random.default_rng(5).gamma(1.0, 1.0, size=(301, 300)).astype(np.float32)
    grid = Grid(data, 0.1, -15.05, -15.0)
    p = FmtParams(cell_m=0.2, size=150)
    k = 2
    plain = data[:300, :300].reshape(150, k, 150, k).mean(axis=(1, 3))
    m = np.array([[1.0, 0.0, (grid.origin_x_m + 0.05) / 0.2 + 75], [0.0, 1.0, (grid.origin_y_m + 0.05) / 0.2 + 75]])
    ref = cv2.warpAffine(plain, m, (150, 150), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    np.testing.assert_array_equal(spectra._resample(grid, p), ref)


def test_older_spectrum_computed_once_per_image():
    a, b = _images()
    r1 = register(a, b, P)
    assert len(a.spectra) == 1
    cached = next(iter(a.spectra.values()))
    folded = b.folded  # the rotation's folded polar spectrum: once per image too
    assert folded is not None and a.folded is not None
    r2 = register(a, b, P)
    assert next(iter(a.spectra.values())) is cached
    assert b.folded is folded
    half = P.angles // 2
    np.testing.assert_array_equal(folded, scipy.fft.rfft(b.polar[:half] + b.polar[half:], axis=0))
    assert (r1.x_m, r1.y_m, r1.theta_rad) == (r2.x_m, r2.y_m, r2.theta_rad)
    assert r1.ok and abs(r1.x_m - 1.3) < 0.2 and abs(r1.y_m + 0.4) < 0.2 and abs(math.degrees(r1.theta_rad) - 4) < 0.5


def test_second_candidate_from_the_conjugate_spectrum_is_the_warped_one():
    # b turned by theta + pi = b turned by theta, then by 180 deg about the centre cell: its spectrum is the
    # conjugate (to the window's half-cell asymmetry), so register's second candidate needs no warp of its own
    for p in (P, FmtParams(cell_m=0.2, size=256, range_min_m=2.5, range_max_m=25.0, taper_m=4.0)):
        a, b = _images(p)
        tr = core._Translator(a, b, p)
        theta = math.radians(4.0)
        fb = tr.spectrum(theta)
        got = tr.translation(theta + math.pi, np.conj(fb))
        want = tr.translation(theta + math.pi)
        assert got[0] == pytest.approx(want[0], rel=0.02)
        np.testing.assert_allclose(got[2:4], want[2:4], atol=0.02 * p.cell_m)
        assert got[0] < tr.translation(theta, fb)[0]  # the wrong candidate: the weaker peak


def test_coarse_search_and_the_translation_returned():
    # on the coarse grid (low-pass 0 beyond 1/4 cycle per cell) the rotations are tried on the images halved by
    # cv2.pyrDown; the translation returned is the full grid's (the coarse-grid peak of the full spectra's rows)
    a, b = _images()
    tr = core._Translator(a, b, P)
    assert tr.rows is not None
    theta = math.radians(4.0)
    hann = transforms.hann_window(a.image.shape)
    # the older one's as prepare() computes it (OpenCV's transform of the rows, scipy.fft's of the kept columns):
    # scipy.fft's rfft2 to float rounding
    fa = transforms.rows_then_columns(a.image * hann, tr.cols)[tr.rows]
    whole = scipy.fft.rfft2(a.image * hann)[:, :tr.cols][tr.rows]
    np.testing.assert_allclose(fa, whole, rtol=0, atol=1e-6 * float(np.abs(whole).max()))
    fb = tr.spectrum(theta, fine=True)
    # b turned by theta in two halves of rows (OpenCV's warp of each from its first row), windowed: its spectrum
    n = b.image.shape[0]
    c, s = math.cos(theta), math.sin(theta)
    halves = [cv2.warpAffine(b.image, np.array([[c, s, n // 2 * (1 - c - s) + s * r0],
                                                [-s, c, n // 2 * (1 + s - c) + c * r0]]), (n, n // 2),
                             flags=cv2.INTER_LINEAR + cv2.WARP_INVERSE_MAP) for r0 in (0, n // 2)]
    plain = scipy.fft.rfft2(np.vstack(halves) * hann)[:, :tr.cols][tr.rows]
    np.testing.assert_allclose(fb, plain, rtol=0, atol=1e-6 * float(np.abs(plain).max()))
    want = correlation.coarse_peak(fa, fb, tr.weight, a.image.shape[0])
    snr, t, x, y, h = tr.final(theta)
    np.testing.assert_array_equal((x, y), (-want[1] * P.cell_m, -want[0] * P.cell_m))  # cells -> m as the code
    assert snr == want[2]
    coarse = tr.translation(theta)  # the search: its SNR only (the peak of the halved images' correlation)
    assert coarse[0] == pytest.approx(snr, rel=0.25)
    assert math.isnan(coarse[2]) and math.isnan(coarse[3])
    assert tr.translation(theta + math.radians(2.0))[0] < coarse[0]  # the SNR falls off the right rotation
    assert abs(x - 1.3) < 0.2 and abs(y + 0.4) < 0.2
    r = register(a, b, P)
    assert (r.x_m, r.y_m, r.snr_translation) == tr.final(r.theta_rad)[2:4] + (tr.final(r.theta_rad)[0],)


@pytest.mark.parametrize("iy, ix", [(40, 70), (0, 127), (125, 2)])
def test_snr_from_sums_is_the_masked_one(iy, ix):
    c = np.random.default_rng(iy + ix).normal(size=(128, 128)).astype(np.float32)
    c[iy, ix] = 30.0
    assert correlation._snr_sums(c, iy, ix) == pytest.approx(correlation.masked_snr(c, iy, ix), rel=1e-5)


def test_whitened_spectrum_is_the_cross_power_over_its_magnitude():
    rng = np.random.default_rng(4)
    fa, fb = ((rng.normal(size=(64, 33)) + 1j * rng.normal(size=(64, 33))).astype(np.complex64) for _ in range(2))
    fa[3, 4] = 0.0
    weight = rng.random((64, 33)).astype(np.float32)
    cross = (fb * np.conj(fa)).astype(np.complex128)
    mag = np.maximum(np.abs(cross), 1e-12 * np.abs(cross).max())
    np.testing.assert_allclose(correlation._whitened(fa, fb, weight), cross / mag * weight, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(correlation._whitened(fa, fb, None), cross / mag, rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize("shape", [(256, 64), (400, 201)])  # under and over numpy's 256 KiB temporary elision
def test_whitened_is_numpys_expression(shape):
    rng = np.random.default_rng(shape[0])
    fa, fb = ((rng.normal(size=shape) + 1j * rng.normal(size=shape)).astype(np.complex64) for _ in range(2))
    weight = rng.random(shape).astype(np.float32)
    for w in (weight, None):
        want = fb * np.conj(fa)  # the expression as numpy rounds it (its temporary elided or not, by size)
        mag = np.abs(want)
        np.maximum(mag, mag.dtype.type(1e-12 * max(float(mag.max()), 1e-30)), out=mag)
        want *= w / mag if w is not None else 1.0 / mag
        np.testing.assert_array_equal(correlation._whitened(fa, fb, w).view(np.uint64), want.view(np.uint64))


@pytest.mark.parametrize("min_wavelength_m", [0.8, 0.0])  # the coarse search, the full grid
def test_registrations_on_two_threads_are_the_one_threads(min_wavelength_m):
    # slam.FmtRegistration runs a registration's independent correlations (the two candidates, the
    # refinement's two neighbours) on `threads` threads: every transform the same bits with 1 and 2
    from impala_flow.msgs import RelativePose2D
    from impala_flow.testing import CollectingSink, ScriptedSource, run_components
    from impala_slam.fmt.component import FmtRegistration

    rng = np.random.default_rng(5)
    world = SyntheticWorld.random(rng, (-60, 60), (-60, 60), density_per_m2=0.02, n_clusters=12)
    truth = [(0.6 * k, 0.1 * k, math.radians(1.5 * k)) for k in range(6)]
    images = [(k * 250_000_000, "image", world.render(pose, rng, cell_m=0.1, radius_m=26.0))
              for k, pose in enumerate(truth)]
    params = dict(cell_m=0.2, size=256, range_min_m=2.5, range_max_m=25.0, taper_m=4.0,
                  min_wavelength_m=min_wavelength_m)
    got = {}
    # and OpenCV's own threads (a graph run leaves cv2 at its default, one per core) split its warps alike
    for threads, cv_threads in ((1, 1), (2, 1), (2, 2)):
        fmt, sink = FmtRegistration("fmt", threads=threads, **params), CollectingSink("sink")
        cv2.setNumThreads(cv_threads)
        try:
            run_components(ScriptedSource("src", images), fmt, sink,
                           connections=["src.image -> fmt.image", "fmt.transform -> sink.x"])
        finally:
            cv2.setNumThreads(1)
        got[threads, cv_threads] = sink.values()
        assert fmt.summary()["images"] == len(images)
    for one, two, two_cv in zip(got[1, 1], got[2, 1], got[2, 2], strict=True):
        for other in (two, two_cv):
            assert isinstance(other, RelativePose2D)
            assert (one.x_m, one.y_m, one.theta_rad, one.kind) == (other.x_m, other.y_m, other.theta_rad, other.kind)
            np.testing.assert_array_equal(one.cov_xyt, other.cov_xyt)
    # and they are the motion (each image's pose in the previous one's frame), to within this sparse world's
    # registration error (the other tests of this file hold the accuracy)
    from impala_slam.se2 import between

    steps = [r for r in got[2, 2] if r.kind == "registration"]
    assert len(steps) >= 4
    for r in steps:
        k = r.to_t_ns // 250_000_000
        want = between(truth[k - 1], truth[k])
        assert math.hypot(r.x_m - want[0], r.y_m - want[1]) < 0.3
        assert abs(math.degrees(r.theta_rad - want[2])) < 1.0


def test_compiled_two_by_two_mean_is_numpys():
    from impala_slam.fmt._jit import mean2x2

    rng = np.random.default_rng(2)
    data = rng.exponential(1.0, (201, 157)).astype(np.float32) * np.float32(1e3)
    h, w = 200, 156
    want = data[:h, :w].reshape(h // 2, 2, w // 2, 2).mean(axis=(1, 3), dtype=np.float32)
    pairs = data[:h, 0:w:2] + data[:h, 1:w:2]  # numpy's order of the sums (the mean above may sum otherwise)
    exact = (pairs[0::2] + pairs[1::2]) / np.float32(4)
    got = mean2x2(data, np.empty((h // 2, w // 2), np.float32))
    np.testing.assert_array_equal(got, exact)
    np.testing.assert_allclose(got, want, rtol=1e-6)


@pytest.mark.parametrize("q", [0.9, 0.5, 0.999, 0.03])
def test_quantile_is_numpys(q):
    # the threshold of step 2: the two order statistics selected among the values over a bound, then numpy's
    # interpolation of the two: the same number as np.quantile, on skewed, flat, tied and tiny arrays
    rng = np.random.default_rng(4)
    cases = [rng.exponential(1.0, 200_000), rng.random(50_000), rng.integers(0, 4, 30_000).astype(float),
             rng.lognormal(0.0, 3.0, 100_001), rng.random(7), np.full(10_000, 2.5)]
    power = _images()[0].image  # a prepared image's values too
    cases.append(power[power > 0].astype(np.float64))
    cases.append(np.concatenate([rng.exponential(10.0, 60_000), rng.exponential(1.0, 60_000)]))  # unlike halves
    for x in cases:
        x = x.astype(np.float32)
        assert spectra._quantile(x.copy(), q) == float(np.quantile(x, q))
        # in two pieces (prepare's halves of rows), each with its own bound, on their threads
        pieces = [x[:x.size // 3].copy(), x[x.size // 3:].copy()]
        assert spectra._quantile_of([(v, *spectra._upper(v, q)) for v in pieces], q) == float(np.quantile(x, q))


@pytest.mark.parametrize("q", [0.9, 0.5])
def test_quantile_of_parts_with_any_bounds_is_numpys(q):
    # each part keeps its values at or above its own bound; the order statistics are taken among those as they
    # are, so a bound over the quantile (some value it left out lies over the k-th) must fall back to numpy's
    rng = np.random.default_rng(11)
    x = np.concatenate([rng.exponential(10.0, 40_000), rng.exponential(1.0, 50_000), np.full(5_000, 3.0)])
    x = x.astype(np.float32)
    want = float(np.quantile(x, q))
    pieces = [x[:45_000], x[45_000:]]
    for qa, qb in [(0.0, 0.0), (0.5, 0.8), (0.85, 0.2), (0.99, 0.5), (0.5, 0.999), (0.95, 0.95)]:
        parts = []
        for v, qq in zip(pieces, (qa, qb), strict=True):
            bound = float(np.quantile(v, qq))
            parts.append((v.copy(), bound, v[v >= bound].copy()))
        assert spectra._quantile_of(parts, q) == want, (qa, qb)


@pytest.mark.parametrize("linear_power,size", [(True, 256), (False, 256), (True, 151)])
def test_preparation_in_halves_of_rows_is_the_whole_images(linear_power, size):
    # prepare(pool=) computes the 2 x 2 mean and the threshold, dB, taper and window in two halves of rows on the
    # pool's threads: the same bits as step 2's formula on the whole image (np.quantile of the observed cells)
    from impala_slam.fmt.parallel import TaskPool

    rng = np.random.default_rng(8)
    world = SyntheticWorld.random(rng, (-60, 60), (-60, 60), density_per_m2=0.02, n_clusters=12)
    grid = world.render((0.0, 0.0, 0.0), rng, cell_m=0.1, radius_m=26.0)
    if not linear_power:
        grid = Grid(np.where(grid.data > 0, 10.0 * np.log10(np.maximum(grid.data, 1e-30)) + 40.0, 0.0).astype(
            np.float32), grid.cell_m, grid.origin_x_m, grid.origin_y_m)
    p = FmtParams(cell_m=0.2, size=size, range_min_m=2.5, range_max_m=25.0, taper_m=4.0, min_wavelength_m=0.8)
    img = spectra._resample(grid, p)
    vals = img[img > 0]
    level = float(np.quantile(vals, p.db_floor_quantile))
    want = np.zeros_like(img)
    keep = img > level
    if linear_power:
        want[keep] = 10.0 * np.log10(img[keep] / level)
    else:
        want[keep] = img[keep] - level
    want *= spectra._taper(p)
    pool = TaskPool(2)
    try:
        alone, halves = prepare(grid, p, linear_power), prepare(grid, p, linear_power, workers=2, pool=pool)
    finally:
        pool.close()
    np.testing.assert_array_equal(alone.image, want)
    np.testing.assert_array_equal(halves.image, want)
    np.testing.assert_array_equal(halves.polar, alone.polar)
    np.testing.assert_array_equal(halves.polar, core.polar_spectrum(want, p))
    assert alone.spectra.keys() == halves.spectra.keys()
    for k in alone.spectra:
        np.testing.assert_array_equal(halves.spectra[k], alone.spectra[k])


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shape", [(64, 64), (48, 63), (10, 8)])
def test_rows_then_columns_is_scipys_rfft2(shape, dtype):
    # prepare()'s transform (OpenCV's of the rows, scipy.fft's of the columns) is scipy.fft's rfft2 to float32
    # rounding, whatever the image's type and width (an odd one: scipy.fft's alone)
    x = np.random.default_rng(shape[1]).random(shape).astype(dtype)
    got, want = transforms.rows_then_columns(x, 5), scipy.fft.rfft2(x)[:, :5]
    assert got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6 * float(np.abs(want).max()))
