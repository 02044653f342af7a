"""Fourier-Mellin registration of two radar images (seed 2, §V, Algorithm 1).

:func:`prepare` brings a panoramic (``Grid``, vehicle frame) onto the registration grid:
``size`` x ``size`` cells of ``cell_m`` centred on the radar, the thresholded power in dB
(step 2: cells under the speckle threshold are 0), a radial taper to the range edge so the
fixed disc of the radar's coverage (the same in both images, whatever the motion) does not
pull the translation to zero. :func:`register` then runs the rest of Algorithm 1:

- steps 3-5: magnitude of the FFT of each image (2-D Hann window,
  ``cv2.createHanningWindow``), high-pass weighted (Reddy & Chatterji) so the low
  frequencies of the coverage disc do not dominate, resampled to polar coordinates with
  bilinear interpolation (``cv2.warpPolar``) over a band of spatial frequencies;
- steps 6-9: the rotation is the shift along the angle axis, by phase correlation of the
  two polar images (one cross-power spectrum along the angle summed over the radii: no
  scale between radar images, so only the zero radial shift is searched). The magnitude
  spectrum of a real image is centro-symmetric: the correlation peaks at theta and
  theta + 180 deg alike, so both are carried on;
- steps 10-14: the newer image is de-rotated for each of the two candidates and phase
  correlated with the older one; the candidate whose translation peak is the stronger is
  kept (the 180 deg ambiguity resolved), sub-cell peak by a quadratic fit of the 3x3 cells
  around the maximum. The second candidate is the first turned by 180 deg about the radar:
  its spectrum is the first's conjugate (a real image), so it costs no warp nor transform;
- beyond Algorithm 1 (``min_wavelength_m``, 0 to switch it off): the translation's
  whitened cross-power spectrum is weighted by a low-pass, 1 up to half the cut-off
  frequency 1 / min_wavelength_m and a cosine roll-off to 0 at it. Whitening gives every
  frequency the same weight, and the finest ones, which the radar does not resolve at range
  (the arc between two azimuths at the outer radius, 2 pi range_max / azimuths: 0.79 m for
  400 azimuths at 50 m), hold no coherent scene between two turns but a pattern fixed in the
  sensor frame (the polar-to-Cartesian sampling of the same azimuths and bins every turn):
  a false peak at zero shift. On the RADIATE Edinburgh head (0.17 m bins, 0.2 m cells, car at
  10 m/s along a wall) it beat the 2.4 m true peak in 55 of 69 pairs at speed (SNR 40-98
  against about 50); at 0.8 m, the per-pair error against R-SLAM fell from 1.9 m to 5 cm
  there and Oxford's pairs improved (7.1 to 5.8 cm, 0.15 to 0.08 deg). Flat between 0.8 and
  1.2 m; the default 0 keeps the whole band (the simulated campus missions, 0.5 m cells,
  whose Nyquist wavelength of 1 m is already coarser). When min_wavelength_m is at least 4
  cells (RADIATE: 0.8 m at 0.2 m cells), the low-pass leaves nothing beyond 1/4 cycle per
  cell, so the correlation surface is band-limited and its values every other cell hold all of
  it (Nyquist): it is computed on an n/2 x n/2 grid (4x smaller inverse transform and peak
  search) and only the 7 x 7 cells around the peak at full resolution (:func:`_coarse_peak`;
  the same peak, Hessian and SNR to float rounding). There, the rotations are also tried on
  the images halved (``cv2.pyrDown``, de-rotated with bicubic interpolation: 4x smaller
  warps and forward transforms): those translations only choose the candidate and the
  rotation; the translation returned is computed at the chosen rotation from the full
  images' spectra, as before. On the 400 RADIATE turns against their GPS (graphs/oxford.yaml):
  ATE 4.028 -> 3.715 m, pairs 0.0965 -> 0.0964 m and 0.6621 -> 0.6620 deg; Oxford's 10 pairs
  5.79 -> 5.80 cm and 0.084 -> 0.083 deg, ATE 0.088 -> 0.087 m; 0.73 of the CPU time per
  registration (with its image's preparation: 35.3 -> 25.8 ms, median, one thread, the old and
  new code alternating on the same 200 RADIATE turns);
- beyond Algorithm 1 (``refine_deg``, 0 to switch it off): the rotation of the magnitude
  spectra is good to about a polar bin (0.5 deg): it is refined by a parabola through the
  translation peak's SNR at theta - step, theta, theta + step, and the translation taken
  again at the refined rotation. On the Oxford pairs it halves the rotation error (0.28 to
  0.15 deg per pair) for 3 to 5 more correlations. That last translation is correlated, never
  interpolated from the three: interpolated when their peaks agreed within a quarter cell (one
  correlation less on the full grid), graphs/fmt_ekf_navtech.yaml's EKF / iSAM2 / LM ATE on the
  RADIATE head went from 1.0098 / 1.0095 / 1.0095 to 1.0115 / 1.0111 / 1.0111 m and campus-loop
  seed 13's EKF from 0.430 to 0.435 m.

Threads (``pool``, slam.FmtRegistration's ``threads``): the two candidates' correlations and each
refinement step's two neighbours do not depend on each other; they run on a pool's threads, and
the transforms outside them on scipy.fft's workers (pocketfft shares a batch of 1-D transforms
between threads, each computed alike): the same bits with 1 thread or 2. CPU per registration
with its image's preparation, one thread, median, the code before and after alternating on the
same 60 RADIATE turns (graphs/oxford.yaml's settings) and 40 campus ones, the 2 cores loaded by
other work (load 10): RADIATE 31.1 -> 26.7 ms, campus 30.5 -> 27.3 ms (the 2 x 2 mean compiled in
one pass, the threshold's quantile selected above a sampled bound, both bit for bit numpy's; the
polar spectrum's magnitude on the square its warp reads; each image's folded polar spectrum
transformed once). On 2 threads the calling thread's CPU, the wall time's floor on an idle
machine, falls to 16.3 ms (RADIATE) and 15.6 ms (campus) of the 25.3 and 25.4 ms it has on one
(the cores were never idle during this work, so no wall figure of an idle machine). With a pool,
:func:`prepare` also computes the 2 x 2 mean and the threshold, dB, taper and window in two halves
of rows, and :func:`register` the rotation beside what the translations need whatever the
rotation (the older image's spectra, the newer one on the coarse grid): the same bits. The calling
thread's CPU on 2 threads, the same 40 RADIATE and 40 campus turns, the code before and after
alternating, four runs at load 1-4: RADIATE 14.2-16.3 -> 13.3-15.5 ms (0.5-0.9 less), campus
13.0-15.1 -> 13.0-15.0 ms (0.0-0.2 less); OpenCV's own threads (a graph run's default, one per
core; the same bits) take 0-0.9 ms more of its warps off it. Wall time (median, load 1.1, the
other sessions still on a core): RADIATE 23.2 ms on one thread, 20.2 on 2 before, 18.5 now with
OpenCV's threads; campus 20.8, 18.0, 17.1. At load 2-4 the 2 threads' wall was no lower than one's
(the second thread waited for a core).

Parameters set on data: the threshold (the 0.9 quantile of the observed power) and the
band of spatial frequencies (0.02-0.25 cycles/cell) on a synthetic world
(:mod:`impala_slam.synthetic`): the 0.5 quantile and the full band left the rotation peak
in the speckle (SNR 3 instead of 15).

The covariance comes from the correlation peaks, not a constant (the seed's): for each
peak, the curvature H of the normalised correlation at the maximum (from the quadratic
fit) and the peak's signal-to-noise ratio (height over the standard deviation of the
correlation away from it) give var = k / (SNR^2 H) + floor^2 in cells^2 (rotation bins
for the rotation): a sharp, strong peak is certain, a weak or elongated one (a corridor,
an open field) is not, and along the right direction (H is a 2x2 matrix for the
translation). The rotation refined on the translation peak (``refine_deg``) takes its
variance from that parabola the same way: k / (SNR c), c = -d2 SNR / d theta2. Terms not
in the peaks: the images are motion-corrected with the odometer and the gyro, whose scale
errors stretch and twist them, so a variance (along_frac |t|)^2 is added along the
translation and (rot_frac theta)^2 + rot_floor^2 to the rotation (the rotation errors of
simulated turns grow from 0.04 deg on straight lines to 0.4 deg in turns of more than
11 deg). The constants were set so that the normalised estimation error squared (NEES) of
consecutive simulated turns against an exact truth is near its chi^2 (3 dof) law: over
campus-open seeds 101, 102 and campus-loop seeds 21, 22, mean 2.3 and median 1.5 (chi^2:
3 and 2.37; open alone 1.8 / 0.95, loop alone 2.9 / 2.1: a little conservative on open
roads). ``tests/slam/test_fmt_ekf.py`` checks it on campus-loop seed 7, never used: median
2.4, mean 4.5 (heavier tails than a Gaussian), 95 % of the pairs under the 95 % bound.

Transforms (issue 26, fourth round). Inside a batch's tasks (the candidates, the refinement's pairs) the 2-D
transforms of the translation are ``cv2.dft``'s on its packed spectrum (CCS; unpacked to rfft2's layout, the
inverse's input packed by a compiled loop), 1.3-2.2 x faster than scipy.fft's on one thread at 256-512 cells;
the transforms no other runs beside stay scipy.fft's on its workers (cv2.dft computes on one thread), and the
translation returned on the coarse grid is warped, windowed and transformed along its rows in two halves of
rows on the pool's threads (the calling thread's share at 512 cells 0.9 ms against 1.7-1.9 ms). Which one is
fixed by where the transform is, never by the number of threads: the same bits with 1 or 2. The surfaces' sum
and sum of squares for the SNR come from the spectrum (its DC term and Parseval), not from another pass over the
surface; :func:`_coarse_peak`'s window from a table of the roots of unity; on the coarse grid an image's
spectrum as the next pair's older one is computed beside its polar spectrum. The numbers move by float32
rounding (1e-7 of the largest coefficient): on 59 RADIATE and 39 campus pairs the registrations by at most
3 um and 4e-7 deg. Accuracy before -> after, the same settings: the RADIATE head through graphs/oxford.yaml FMT
ATE 3.7094013 -> 3.7094003 m, through graphs/fmt_ekf_navtech.yaml EKF / iSAM2 / LM 1.0098263 / 1.0095161 /
1.0095207 -> 1.0098277 / 1.0095174 / 1.0095222 m; Oxford's pairs 5.7959 -> 5.7959 cm, 0.08328 deg, ATE
0.0870512 m (-0.03 um); campus-open 60 s seeds 29, 31, 41, 13, 47, 53 FMT ATE summed 2.1341991 -> 2.1341981 m
(4 seeds of 6 lower): equal, to the micrometre. CPU per registration with its image's preparation, median,
the code before and after alternating on the same 60 RADIATE and 40 campus turns (graphs/oxford.yaml's and
bench/speed.py's settings; load 5-7, so the absolute figures high): one thread RADIATE 26.8 -> 24.0 ms (-11 %),
campus 28.5 -> 26.0 ms (-9 %); on 2 threads (OpenCV's on 2, as in a graph run) the calling thread's, the
wall time's floor, RADIATE 17.8 -> 16.5 ms, campus 18.0 -> 16.2 ms. scipy.fft is imported in the
components' start() (:func:`warm_up`), not with this module: importing slam.FmtRegistration's module costs
48 ms of CPU instead of 264 ms when nothing else has imported scipy.fft.

Off the calling thread (issue 26, fourth round, second part), the same bits (every registration and prepared
image of 25 RADIATE turns at both its settings and 25 campus turns, 1 and 2 threads, OpenCV on 1 and 2): the
resampling's shift warped in two halves of rows, each half's observed values and their maximum taken after it on
the same thread; the whitenings nothing runs beside in two halves of rows (numpy's temporary elision, which
decides how fb * conj(fa) is rounded, made explicit); the windowed image only on the path that transforms it.
The calling thread's CPU per registration on 2 threads, median, the code before and after alternating on the
same 60 RADIATE and 40 campus turns (load 1.3-1.6): with OpenCV on one thread (bench/speed.py's) RADIATE 13.06
-> 12.74 and 12.41 -> 12.18 ms (two runs), campus 13.27 -> 13.02 and 13.36 -> 13.05 ms; with OpenCV on 2 (a
graph run's), whose own threads already share the whole warp, no change (12.24 -> 12.34, campus 12.66 -> 12.72).
Measured and left: (1) the coarse search's de-rotation bilinear instead of bicubic (3.4 x cheaper at 256 cells:
-1.2 ms on the calling thread, -1.8 ms on one): the RADIATE head's FMT ATE 3.7094 -> 3.2040 m and 3 of 4 campus
seeds on the coarse grid (min_wavelength_m 2 m) better, but Oxford's pairs' rotation 0.0833 -> 0.1020 deg and ATE
0.0871 -> 0.0880 m: bilinear's blur depends on the rotation's fractional offsets and biases the refinement's
parabola, as this module said. (2) The spectra nothing runs beside (the first candidate's, a lone refinement
step's, the last) in halves of rows on the pool like the translation returned: accuracy equal to the micrometre
(the 6 campus seeds' ATE summed -3 um, RADIATE FMT -6 um, fmt_ekf_navtech +5 um), the calling thread -0.2 ms
with OpenCV on one thread but +0.1 to +0.5 ms with OpenCV on 2 and no lower wall: not kept.

I deliberately compute the correlation surfaces with scipy.fft and cv2.dft instead of calling
``cv2.phaseCorrelate``: it returns only the peak, and the covariance needs the surface.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from impala_flow.msgs import Grid

from .parallel import TaskPool

__all__ = ["FmtParams", "FmtImage", "FmtResult", "prepare", "polar_spectrum", "register", "register_grids",
           "phase_correlation", "warm_up"]


@dataclass(frozen=True)
class FmtParams:
    cell_m: float = 0.5  # cell of the registration grid
    size: int = 400  # cells per side (the grid spans +- size * cell_m / 2)
    range_min_m: float = 3.0  # blind range: zeroed
    range_max_m: float = 0.0  # outer radius used (0: the grid's half side)
    taper_m: float = 15.0  # width of the radial cosine taper before range_max_m
    db_floor_quantile: float = 0.9  # cells above this quantile of the observed power are kept (step 2)
    angles: int = 720  # rows of the polar magnitude spectrum over 360 deg
    band: tuple[float, float] = (0.02, 0.25)  # spatial frequencies used for the rotation (cycles / cell)
    k_translation: float = 5.0  # covariance constants (see the module docstring)
    k_rotation: float = 40.0  # rotation from the spectra alone (refine_deg = 0)
    k_rotation_refined: float = 20.0  # rotation refined on the translation peak
    floor_cells: float = 0.06  # std floor of each peak (cells, rotation bins)
    along_frac: float = 0.01  # std along the translation per metre (the odometer's scale in the images)
    rot_frac: float = 0.02  # rotation std per radian turned between the images (the gyro's, likewise)
    rot_floor_deg: float = 0.05  # rotation std the peaks never see (the gyro's bias in the motion correction)
    min_snr: float = 6.0  # a translation peak weaker than this is not a registration
    refine_deg: float = 0.5  # step of the rotation refinement on the translation peak (0: Algorithm 1 only)
    min_wavelength_m: float = 0.0  # finest spatial wavelength in the translation correlation (0: up to Nyquist)


@dataclass
class FmtImage:
    """An image ready to register: the tapered dB image and its polar magnitude spectrum."""

    image: np.ndarray  # float32 size x size, row = y, column = x, radar at the centre
    polar: np.ndarray  # angles x radii, float32: high-passed |FFT| in polar coordinates
    cell_m: float
    # rfft2 of image * Hann by number of columns kept (see _spectrum): computed once however often
    # the image is registered as the older one
    spectra: dict[int, np.ndarray] = field(default_factory=dict, repr=False, compare=False)
    # the image on the coarse grid (_half) and its spectrum by number of columns kept
    half: np.ndarray | None = field(default=None, repr=False, compare=False)
    half_spectra: dict[int, np.ndarray] = field(default_factory=dict, repr=False, compare=False)
    # the rotation's spectrum of the polar image folded onto half a turn (_folded_spectrum)
    folded: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def nbytes(self) -> int:
        return (self.image.nbytes + self.polar.nbytes + sum(s.nbytes for s in self.spectra.values())
                + (0 if self.half is None else self.half.nbytes) + sum(s.nbytes for s in self.half_spectra.values())
                + (0 if self.folded is None else self.folded.nbytes))


@dataclass
class FmtResult:
    """Pose of the newer image's frame in the older one's, with its 3x3 covariance."""

    x_m: float
    y_m: float
    theta_rad: float
    cov_xyt: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    snr_translation: float = 0.0
    snr_rotation: float = 0.0
    ok: bool = False
    reason: str = ""

    @property
    def xyt(self) -> tuple[float, float, float]:
        return self.x_m, self.y_m, self.theta_rad


# --- preparation (steps 1-2 and the spectrum of steps 3-5) ------------------------------

_windows: dict[tuple[int, int], np.ndarray] = {}
_highpass: dict[int, np.ndarray] = {}
_tapers: dict[tuple, np.ndarray] = {}
_lowpass: dict[tuple, np.ndarray | None] = {}


def _hann(shape: tuple[int, int]) -> np.ndarray:
    if shape not in _windows:
        _windows[shape] = cv2.createHanningWindow((shape[1], shape[0]), cv2.CV_32F)
    return _windows[shape]


def _high_pass(n: int) -> np.ndarray:
    """Reddy & Chatterji's high-pass (1 - X)(2 - X), X = cos(pi u) cos(pi v), centred spectrum."""
    if n not in _highpass:
        f = np.fft.fftshift(np.fft.fftfreq(n))
        x = np.outer(np.cos(np.pi * f), np.cos(np.pi * f))
        _highpass[n] = ((1.0 - x) * (2.0 - x)).astype(np.float32)
    return _highpass[n]


def _taper(p: FmtParams) -> np.ndarray:
    key = (p.size, p.cell_m, p.range_min_m, p.range_max_m, p.taper_m)
    if key not in _tapers:
        c = (np.arange(p.size) - p.size // 2) * p.cell_m
        r = np.hypot(c[None, :], c[:, None])
        r_max = p.range_max_m or p.size * p.cell_m / 2.0
        w = np.clip((r_max - r) / max(p.taper_m, 1e-9), 0.0, 1.0)
        w = 0.5 - 0.5 * np.cos(np.pi * w)
        w[r < p.range_min_m] = 0.0
        _tapers[key] = w.astype(np.float32)
    return _tapers[key]


def _low_pass(n: int, cell_m: float, min_wavelength_m: float) -> np.ndarray | None:
    """Weight of the whitened cross-power spectrum (``rfft2`` layout of an n x n image): 1 up
    to half the cut-off frequency 1 / min_wavelength_m, a cosine roll-off to 0 at it; None
    when the cut-off is at or beyond Nyquist (the whole band, Algorithm 1 as written)."""
    key = (n, cell_m, min_wavelength_m)
    if key not in _lowpass:
        fc = cell_m / min_wavelength_m if min_wavelength_m > 0 else np.inf  # cycles / cell
        if fc >= 0.5 * math.sqrt(2):
            _lowpass[key] = None
        else:
            f = np.hypot(np.fft.fftfreq(n)[:, None], np.fft.rfftfreq(n)[None, :])
            u = np.clip((f - 0.5 * fc) / (0.5 * fc), 0.0, 1.0)
            _lowpass[key] = (0.5 + 0.5 * np.cos(np.pi * u)).astype(np.float32)
    return _lowpass[key]


def _resample(grid: Grid, p: FmtParams, pool: TaskPool | None = None) -> np.ndarray:
    """The grid's values on the registration grid (radar at cell size // 2, axes kept); ``pool``:
    the 2 x 2 mean and the warp in halves of rows on its threads (the same numbers)."""
    return _resample_parts(grid, p, pool)[0]


def _resample_parts(grid: Grid, p: FmtParams, pool: TaskPool | None = None,
                    then: Callable[[np.ndarray, int, int], Any] | None = None) -> tuple[np.ndarray, list]:
    """:func:`_resample`'s image and the list of ``then(image, r0, r1)`` on its rows r0..r1: with a pool, on
    each half of rows after that half's warp, on the pool's threads; without, once on the whole image (``then``
    None: an empty list)."""
    data = np.ascontiguousarray(grid.data, np.float32)
    s = grid.cell_m / p.cell_m
    # registration pixel = s * grid pixel + offset, the vehicle origin -> centre cell
    m = np.array([[s, 0.0, grid.origin_x_m / p.cell_m + p.size // 2],
                  [0.0, s, grid.origin_y_m / p.cell_m + p.size // 2]])
    interp = cv2.INTER_AREA if s < 1.0 else cv2.INTER_LINEAR
    if s < 1.0 and abs(1.0 / s - round(1.0 / s)) < 1e-6:  # integer reduction: average the cells
        k = int(round(1.0 / s))
        h, w = (data.shape[0] // k) * k, (data.shape[1] // k) * k
        if k == 2:  # the mean below, summed in numpy's order (bit-identical), in one compiled pass
            from ._jit import mean2x2

            src, data = data, np.empty((h // 2, w // 2), np.float32)  # ((x00 + x01) + (x10 + x11)) / 4
            _halves(pool, lambda r0, r1: mean2x2(src[2 * r0:2 * r1], data[r0:r1]), h // 2)
        else:
            data = data[:h, :w].reshape(h // k, k, w // k, k).mean(axis=(1, 3))
        m = np.array([[1.0, 0.0, (grid.origin_x_m + 0.5 * (k - 1) * grid.cell_m) / p.cell_m + p.size // 2],
                      [0.0, 1.0, (grid.origin_y_m + 0.5 * (k - 1) * grid.cell_m) / p.cell_m + p.size // 2]])
        # a shift only: warped in two halves of rows, with or without a pool (so the same numbers with 1 thread or
        # 2), each from its first row (the shift's row offset less r0). OpenCV computes the coordinates in float32:
        # the same numbers as the whole image's warp whenever the offsets less r0 are exact in float32, as the
        # panoramics' are (multiples of 1/4 cell: every RADIATE and campus grid checked)
        out = np.empty((p.size, p.size), data.dtype)

        def warp(r0: int, r1: int) -> Any:
            mr = m.copy()
            mr[1, 2] -= r0
            cv2.warpAffine(data, mr, (p.size, r1 - r0), dst=out[r0:r1], flags=cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            return then(out, r0, r1) if then is not None and pool is not None and pool.threads > 1 else None

        mid = p.size // 2
        if pool is not None and pool.threads > 1:
            return out, pool.map(warp, [(0, mid), (mid, p.size)])
        warp(0, mid)
        warp(mid, p.size)
        return out, [] if then is None else [then(out, 0, p.size)]
    img = cv2.warpAffine(data, m, (p.size, p.size), flags=interp, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return img, [] if then is None else _halves(pool, lambda r0, r1: then(img, r0, r1), p.size)


def warm_up() -> None:
    """Load the compiled loops (numba, from its cache) and scipy.fft now rather than in the first turn (a
    component's start(): the plugin's import, which every command pays, never imports scipy.fft)."""
    import scipy.fft  # noqa: F401 - the rotation's 1-D transforms

    from ._jit import mean2x2, pack_ccs, sum_sq

    mean2x2(np.zeros((2, 2), np.float32), np.empty((1, 1), np.float32))
    pack_ccs(np.zeros((4, 3), np.complex64), np.empty((4, 4), np.float32))
    sum_sq(np.zeros((4, 3), np.complex64), 4)


def _quantile(vals: np.ndarray, q: float) -> float:
    """``np.quantile(vals, q)`` (linear, the default method), the same number, ``vals`` reordered: the
    two order statistics it interpolates are selected among the values at or above a bound taken
    low on a sample (the exact ones whenever fewer values than the lower rank lie under it, else the
    whole array is partitioned as numpy does), then numpy interpolates them with the same weight
    (its virtual index (n - 1) q, here on two values: the same float64 fraction and formula)."""
    n = vals.size
    v = (n - 1) * q  # numpy's virtual index (float64), its floor and fraction
    k = int(math.floor(v))
    if n < 4096 or k + 1 >= n:
        return float(np.quantile(vals, q, overwrite_input=True))
    sample = vals[::64].copy()
    j = max(int((q - 0.05) * (sample.size - 1)), 0)  # well under the sample's q-quantile
    bound = np.partition(sample, j)[j]
    top = vals[vals >= bound]
    below = n - top.size
    if below > k:  # the bound was not under the k-th value: numpy's own selection
        return float(np.quantile(vals, q, overwrite_input=True))
    top.partition((k - below, k - below + 1))
    pair = np.array([top[k - below], top[k - below + 1]], vals.dtype)
    return float(np.quantile(pair, v - k, overwrite_input=True))


def prepare(grid: Grid, params: FmtParams | None = None, linear_power: bool = True, workers: int = 1,
            pool: TaskPool | None = None) -> FmtImage:
    """Steps 1-5 for one image: resample, threshold (step 2), dB, taper; polar |FFT|.

    ``linear_power``: the grid holds power (the panoramic builder); False if already in dB
    (Navtech PNGs). ``workers``: scipy.fft's threads for its transform; ``pool``: the element-wise
    steps in halves of rows on its threads (each cell computed alike: the same numbers)."""
    with fft_workers(workers):
        return _prepare(grid, params or FmtParams(), linear_power, pool)


def _halves(pool: TaskPool | None, fn: Callable[[int, int], Any], rows: int) -> list:
    """``fn(r0, r1)`` on the two halves of ``rows`` on the pool's threads (one call without a pool)."""
    if pool is None or pool.threads < 2:
        return [fn(0, rows)]
    h = rows // 2
    return pool.map(fn, [(0, h), (h, rows)])


def _prepare(grid: Grid, p: FmtParams, linear_power: bool, pool: TaskPool | None = None) -> FmtImage:
    def observed_of(img: np.ndarray, r0: int, r1: int) -> tuple[np.ndarray, float]:
        part = img[r0:r1]
        vals = part[part > 0]
        return vals, float(vals.max()) if vals.size else 0.0

    # the observed values in row order (img[img > 0]) and their maximum, a half of the rows each, after that
    # half's warp
    img, parts = _resample_parts(grid, p, pool, observed_of)
    vals = np.concatenate([v for v, _ in parts])
    n = img.shape[0]
    out = np.zeros_like(img)
    hann = _hann(out.shape)
    hi = int(p.band[1] * n)
    square = out.shape[1] == n and n % 2 == 0 and hi + 4 < n // 2  # the polar spectrum from the rfft2 kept
    windowed = np.empty_like(img) if square else None  # every cell written by finish(); only that path uses it
    if vals.size:
        if linear_power:
            level = _quantile(vals, p.db_floor_quantile)  # vals: reordered
            level = max(level, max(m for _, m in parts) * 1e-12, np.finfo(np.float32).tiny)
        else:
            level = _quantile(vals, p.db_floor_quantile)
    taper = _taper(p)

    def finish(r0: int, r1: int) -> None:  # threshold, dB, taper and window of rows r0..r1
        o = out[r0:r1]
        if vals.size:
            part = img[r0:r1]
            keep = part > level
            o[keep] = 10.0 * np.log10(part[keep] / level) if linear_power else part[keep] - level
        o *= taper[r0:r1]
        if windowed is not None:
            np.multiply(o, hann[r0:r1], out=windowed[r0:r1])

    _halves(pool, finish, n)
    lp = _low_pass(n, p.cell_m, p.min_wavelength_m)
    cols, _ = _columns(out.shape, lp, True)
    if windowed is not None:
        # the windowed image's rfft2 serves twice: the polar spectrum's magnitude and, when this
        # image is the older one of a pair, the translation's spectrum on the full grid (_spectrum)
        rf = _rfft2(windowed, max(cols, hi + 4), cv=False)  # scipy.fft's: the rotation's spectra as before, bit for bit
        fi = FmtImage(out, np.empty((0, 0), np.float32), p.cell_m, {cols: np.ascontiguousarray(rf[:, :cols])})
        if _coarse_rows(n, lp, cols) is None:
            fi.polar = polar_spectrum(out, p, rf)
            return fi
        # on the coarse grid, the spectrum this image will have as the older one of the next pair, beside its
        # polar spectrum (the same numbers as computed then: scipy.fft's, here rather than beside the rotation)
        fi.polar = pool.map(_call, [(polar_spectrum, out, p, rf), (_spectrum, fi, cols, True)])[0] if pool else \
            polar_spectrum(out, p, rf)
        if not pool:
            _spectrum(fi, cols, True)
        return fi
    return FmtImage(out, polar_spectrum(out, p), p.cell_m)


def polar_spectrum(img: np.ndarray, p: FmtParams, rf: np.ndarray | None = None) -> np.ndarray:
    """Steps 3-5: the high-passed |FFT| of the windowed image in polar coordinates over the band;
    ``rf``: the windowed image's rfft2 (its first columns, at least the band's radius + 4) if known."""
    n = img.shape[0]
    radii = n // 2
    lo, hi = int(p.band[0] * n), int(p.band[1] * n)  # radius of f cycles/cell = f * n pixels
    flags = cv2.INTER_LINEAR + cv2.WARP_FILL_OUTLIERS + cv2.WARP_POLAR_LINEAR
    centre = (float(n // 2), float(n // 2))  # the DC bin
    if img.shape[1] == n and n % 2 == 0 and hi + 4 < radii:
        # only the radii up to the band's are resampled (one pixel per radius as over the whole
        # half side: the same numbers), from the spectrum within them
        m = hi + 4
        spec = _magnitude(img * _hann(img.shape) if rf is None else None, m, rf, n)
        c = n // 2  # the high-pass on the square the warp reads (radius < hi, 2 x 2 neighbours): 0 beyond
        spec[c - m:c + m, c - m:c + m] *= _high_pass(n)[c - m:c + m, c - m:c + m]
        polar = cv2.warpPolar(spec, (hi, p.angles), centre, hi, flags)
    else:
        import scipy.fft

        spec = np.abs(scipy.fft.fftshift(scipy.fft.fft2(img * _hann(img.shape), workers=1))).astype(np.float32)
        spec *= _high_pass(n)
        polar = cv2.warpPolar(spec, (radii, p.angles), centre, radii, flags)
    band = polar[:, lo:hi]
    return np.ascontiguousarray(band / max(float(band.std()), 1e-12), np.float32)


def _magnitude(img: np.ndarray | None, m: int, rf: np.ndarray | None = None, n: int = 0) -> np.ndarray:
    """``abs(fftshift(fft2(img)))`` of a real n x n image (n even) within m rows and m columns of
    the DC bin (0 beyond), the same numbers from m columns of its rfft2: fft2 of a real image is its
    rfft2 with the other half (and the second half of column 0) filled by symmetry,
    F(-u, -v) = conj F(u, v). ``rf``: the image's rfft2 (at least m columns) if known."""
    if rf is None:
        n = img.shape[0]
        rf = _rfft2(img, m, cv=False)
    a = np.abs(rf[:, :m])
    # written straight into fftshift's layout (row and column r -> (r + n/2) mod n), no roll:
    # columns 0..m-1, the second half of column 0, then columns n-m+1..n-1 by symmetry; the rows
    # h-m..h+m-1 only (frequencies -m..m-1)
    h = n // 2
    out = np.zeros((n, n), a.dtype)
    rows = np.arange(h - m, h + m)
    out[h - m:h + m, h:h + m] = a[(rows - h) % n]
    out[h - m:h, h] = a[m:0:-1, 0]  # the second half of column 0 (its row h: DC, set above)
    out[h - m:h + m, h - m + 1:h] = a[(h - rows) % n][:, m - 1:0:-1]
    return out


# --- phase correlation ---------------------------------------------------------------

def _quadratic_peak(c: np.ndarray, iy: int, ix: int) -> tuple[float, float, np.ndarray]:
    """Sub-cell peak of a periodic surface by the quadratic through the 3x3 cells around
    (iy, ix): offsets (dy, dx) and the 2x2 Hessian of -c / c(peak) (1 / cells^2)."""
    ny, nx = c.shape
    w = np.array([[c[(iy + a) % ny, (ix + b) % nx] for b in (-1, 0, 1)] for a in (-1, 0, 1)], float)
    c0 = max(w[1, 1], 1e-12)
    gx = (w[1, 2] - w[1, 0]) / 2.0
    gy = (w[2, 1] - w[0, 1]) / 2.0
    hxx = w[1, 2] - 2 * w[1, 1] + w[1, 0]
    hyy = w[2, 1] - 2 * w[1, 1] + w[0, 1]
    hxy = (w[2, 2] - w[2, 0] - w[0, 2] + w[0, 0]) / 4.0
    h = -np.array([[hyy, hxy], [hxy, hxx]])
    try:
        d = np.linalg.solve(h, np.array([gy, gx]))
    except np.linalg.LinAlgError:
        d = np.zeros(2)
    if not np.all(np.isfinite(d)) or np.any(np.abs(d) > 1.0):
        d = np.zeros(2)
    return float(d[0]), float(d[1]), h / c0


def phase_correlation(a: np.ndarray, b: np.ndarray,
                      weight: np.ndarray | None = None) -> tuple[float, float, float, np.ndarray]:
    """Shift (dy, dx) in cells such that b(q) = a(q - d), its peak SNR and the normalised
    Hessian of the peak (eq. 1 of seed 2: normalised cross-power spectrum, inverse FFT)."""
    cols, w = _columns(a.shape, weight)
    return _peak(*_correlate_sums(_rfft2(a, cols), _rfft2(b, cols), w, a.shape))


def _columns(shape: tuple[int, ...], weight: np.ndarray | None, cache: bool = False) -> tuple[int, np.ndarray | None]:
    """Columns of the rfft2 layout the correlation needs (those where the weight is not 0, all
    without a weight) and the weight on them; ``cache``: the weight is one of :func:`_low_pass`'s
    (kept for the process's life, so its id names it)."""
    if weight is None:
        return shape[1] // 2 + 1, None
    key = (id(weight), weight.shape)
    if cache and key in _columns_of:
        return _columns_of[key]
    nz = np.any(weight != 0, axis=0)
    cols = int(np.flatnonzero(nz)[-1]) + 1 if np.any(nz) else 1
    out = cols, np.ascontiguousarray(weight[:, :cols])
    if cache:
        _columns_of[key] = out
    return out


_columns_of: dict[tuple, tuple[int, np.ndarray]] = {}


_local = threading.local()


def _workers() -> int:
    """scipy.fft's threads for this thread's transforms (:func:`fft_workers`; 1 by default). pocketfft shares
    a batch of 1-D transforms between them, each computed alike: the same numbers with any number."""
    return getattr(_local, "workers", 1)


@contextmanager
def fft_workers(n: int) -> Iterator[None]:
    """This thread's transforms on ``n`` threads within the block (:func:`_workers`)."""
    old = _workers()
    _local.workers = n
    try:
        yield
    finally:
        _local.workers = old


def _batched() -> bool:
    """Whether this thread computes a task of a batch of translations (:meth:`_Translator.translations`,
    with or without a pool): its 2-D transforms are then ``cv2.dft``'s, one thread each, faster than
    scipy.fft's on one; elsewhere (a transform no other runs beside) scipy.fft's, which shares one between
    its ``workers`` (the same numbers with any number). Set by where the transform is, never by the number
    of threads: the same bits with 1 thread or 2."""
    return getattr(_local, "batched", False)


@contextmanager
def _in_batch() -> Iterator[None]:
    old = _batched()
    _local.batched = True
    try:
        yield
    finally:
        _local.batched = old


def _even(shape: tuple[int, ...]) -> bool:
    """An image OpenCV's packed spectrum (CCS) is laid out for here: 2-D, both sides even."""
    return len(shape) == 2 and shape[0] % 2 == 0 and shape[1] % 2 == 0 and min(shape) >= 4


def _rfft2(img: np.ndarray, cols: int, cv: bool | None = None) -> np.ndarray:
    """``scipy.fft.rfft2(img)``'s first ``cols`` columns, to float rounding: for a float32 image of even sides,
    ``cv2.dft``'s packed spectrum (CCS) unpacked to rfft2's layout (1.3-2.2 x faster than scipy.fft's on one
    thread at 256-512 cells, the unpacking included; the same sums to float32 rounding, 1e-7 of the largest
    coefficient), in a batch's task (``cv`` None: :func:`_batched`) or when ``cv``; otherwise scipy.fft's on
    :func:`_workers`' threads: the real transform of the rows then the transform of the kept columns."""
    if (_batched() if cv is None else cv) and img.dtype == np.float32 and _even(img.shape):
        return _unpack_ccs(cv2.dft(img), cols)
    import scipy.fft

    if cols >= img.shape[1] // 2 + 1:
        return scipy.fft.rfft2(img, workers=_workers())
    w = _workers()
    return scipy.fft.fft(scipy.fft.rfft(img, axis=1, workers=w)[:, :cols], axis=0, workers=w)


def _unpack_ccs(ccs: np.ndarray, cols: int) -> np.ndarray:
    """The first ``cols`` columns of rfft2's layout (complex64) from ``cv2.dft``'s packed spectrum of an even
    rows x n real image (:func:`impala_slam.fmt._jit.pack_ccs`'s layout): the (re, im) pairs of columns
    1 .. n/2 - 1 read as complex, columns 0 and n/2 unpacked from the first and last columns (Hermitian)."""
    rows, n = ccs.shape
    h, half = n // 2, rows // 2
    out = np.empty((rows, cols), np.complex64)
    inner = min(cols, h)
    if inner > 1:
        out[:, 1:inner] = ccs[:, 1:2 * inner - 1].view(np.complex64)
    for c, col in ((0, 0), (h, n - 1)):
        if c < cols:
            v, o = ccs[:, col], out[:, c]
            o[0] = v[0]
            o[1:half].real = v[1:rows - 1:2]
            o[1:half].imag = v[2:rows - 1:2]
            o[half] = v[rows - 1]
            o[half + 1:] = np.conj(o[half - 1:0:-1])
    return out


def _irfft2(spec: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, float]:
    """``scipy.fft.irfft2(spec, s=shape)`` (the columns of ``spec`` beyond its own are 0), to float rounding,
    and the sum of |X|^2 over the whole (Hermitian) spectrum: Parseval, the surface's sum of squares times its
    size. In a batch's task (:func:`_batched`), for complex64 and even sides, ``cv2.dft``'s real inverse of the
    packed spectrum (CCS); otherwise scipy.fft's, the inverse of the columns then the real inverse of the rows."""
    if _batched() and spec.dtype == np.complex64 and _even(shape) and spec.shape[1] <= shape[1] // 2 + 1:
        from ._jit import pack_ccs

        ccs = np.empty(shape, np.float32)
        s2 = pack_ccs(np.ascontiguousarray(spec), ccs)
        return cv2.dft(ccs, flags=cv2.DFT_INVERSE | cv2.DFT_REAL_OUTPUT | cv2.DFT_SCALE), s2
    import scipy.fft

    from ._jit import sum_sq

    w = _workers()
    s2 = sum_sq(np.ascontiguousarray(spec), shape[1])
    if spec.shape[1] >= shape[1] // 2 + 1:
        return scipy.fft.irfft2(spec, s=shape, workers=w), s2
    # irfft2 = the inverse transform of the columns, then the real inverse of the rows, scaled once
    # by 1 / (ny nx) at the end: the same numbers, without transforming the columns that are zero
    full = np.zeros((shape[0], shape[1] // 2 + 1), spec.dtype)
    full[:, :spec.shape[1]] = scipy.fft.ifft(spec, axis=0, norm="forward", workers=w)
    c = scipy.fft.irfft(full, n=shape[1], axis=1, norm="forward", workers=w)
    c *= c.dtype.type(1.0 / (shape[0] * shape[1]))
    return c, s2


_ELIDE_BYTES = 256 * 1024  # numpy's NPY_MIN_ELIDE_BYTES


def _whitened(fa: np.ndarray, fb: np.ndarray, weight: np.ndarray | None, pool: TaskPool | None = None) -> np.ndarray:
    """The normalised cross-power spectrum of eq. 1 (seed 2), times ``weight`` when given; ``pool``: in two
    halves of rows on its threads (each coefficient computed alike, the largest magnitude of both halves'
    maxima: the same numbers)."""
    rows = fa.shape[0]
    # numpy computes fb * conj(fa) as conj(fa) * fb written over conj(fa)'s temporary when that holds at least
    # NPY_MIN_ELIDE_BYTES (its temporary elision), into a new array otherwise, and the two can differ in the
    # last bit: the same choice made here explicitly, by the whole spectrum's size, for the halves too
    inplace = fa.nbytes >= _ELIDE_BYTES and fa.shape == fb.shape
    cross = np.empty(fb.shape, np.result_type(fa, fb)) if not inplace else np.conj(fa)

    def product(r0: int, r1: int) -> tuple[np.ndarray, float]:
        c = cross[r0:r1]
        if inplace:
            np.multiply(c, fb[r0:r1], out=c)  # the elided product's operands: the temporary first
        else:
            c[...] = fb[r0:r1] * np.conj(fa[r0:r1])
        mag = np.abs(c)
        return mag, float(mag.max()) if mag.size else 0.0

    def scale(r0: int, r1: int, mag: np.ndarray, top: float) -> None:
        np.maximum(mag, mag.dtype.type(1e-12 * max(top, 1e-30)), out=mag)
        # times a real factor (weight / |cross|), not a complex division
        cross[r0:r1] *= np.divide(weight[r0:r1], mag, out=mag) if weight is not None else np.reciprocal(mag, out=mag)

    spans = [(0, rows)] if pool is None or pool.threads < 2 or rows < 2 else [(0, rows // 2), (rows // 2, rows)]
    parts = pool.map(product, spans) if len(spans) > 1 else [product(0, rows)]
    top = max(m for _, m in parts)
    if len(spans) > 1:
        pool.map(scale, [(r0, r1, mag, top) for (r0, r1), (mag, _) in zip(spans, parts, strict=True)])
    else:
        scale(0, rows, parts[0][0], top)
    return cross


def _correlate(fa: np.ndarray, fb: np.ndarray, weight: np.ndarray | None, shape: tuple[int, ...]) -> np.ndarray:
    """The phase correlation surface from two images' (first columns of) rfft2: the whitened
    cross-power spectrum, weighted, transformed back (the columns left out are zero). The
    surface over the whole spectrum to float32 rounding: numpy's complex64 product of the same
    numbers can differ in the last bit with the arrays' sizes (every registration of the
    512-cell RADIATE turns came out bit-identical; tests/slam/test_fmt_core.py)."""
    return _correlate_sums(fa, fb, weight, shape)[0]


def _correlate_sums(fa: np.ndarray, fb: np.ndarray, weight: np.ndarray | None, shape: tuple[int, ...],
                    pool: TaskPool | None = None) -> tuple[np.ndarray, tuple[float, float]]:
    """:func:`_correlate`'s surface and its sum and sum of squares, from the spectrum (its DC term, and
    Parseval: sum c^2 = sum |X|^2 / size), for :func:`_peak`'s SNR without another pass over the surface;
    ``pool``: the whitening in halves on its threads (the same numbers)."""
    cross = _whitened(fa, fb, weight, pool)
    c, s2 = _irfft2(cross, (shape[0], shape[1]))
    return c, (float(cross[0, 0].real), s2 / (shape[0] * shape[1]))


def _peak(c: np.ndarray, sums: tuple[float, float] | None = None) -> tuple[float, float, float, np.ndarray]:
    """The correlation surface's peak: shift (dy, dx) in cells, SNR, normalised Hessian; ``sums``: the
    surface's sum and sum of squares if known (:func:`_correlate_sums`)."""
    iy, ix = np.unravel_index(int(np.argmax(c)), c.shape)
    dy, dx, h = _quadratic_peak(c, int(iy), int(ix))
    snr = _snr_sums(c, int(iy), int(ix), sums=sums)
    ny, nx = c.shape
    sy = (iy + dy + ny / 2) % ny - ny / 2
    sx = (ix + dx + nx / 2) % nx - nx / 2
    return float(sy), float(sx), snr, h


def _snr(c: np.ndarray, iy: int, ix: int, guard: int = 3) -> float:
    """Peak height over the standard deviation of the surface away from the peak."""
    ny, nx = c.shape
    rows = np.arange(iy - guard, iy + guard + 1) % ny
    cols = np.arange(ix - guard, ix + guard + 1) % nx
    if 2 * guard + 1 >= min(ny, nx):  # the window wraps onto itself: the mask, plainly
        mask = np.ones(c.shape, bool)
        mask[np.ix_(rows, cols)] = False
        rest = c[mask]
    else:
        rest = _outside(c, rows, cols)
    if rest.size == 0:
        return 0.0
    # rest.mean() and rest.std() as numpy computes them (the same sums and roundings: the sum
    # divided by the count in float64, rounded to the array's type), the mean summed once
    t, n = rest.dtype.type, np.intp(rest.size)
    mean = t(rest.sum() / n)
    dev = rest - mean
    np.multiply(dev, dev, out=dev)
    sd = float(t(np.sqrt(t(dev.sum() / n))))
    return float((c[iy, ix] - mean) / sd) if sd > 0 else 0.0


def _snr_sums(c: np.ndarray, iy: int, ix: int, guard: int = 3, sums: tuple[float, float] | None = None) -> float:
    """:func:`_snr` from the whole surface's sum and sum of squares (``sums`` if given, else
    ``cv2.meanStdDev``'s, in float64) less the window's: the same figure to float rounding, without
    copying the surface."""
    ny, nx = c.shape
    if 2 * guard + 1 >= min(ny, nx):
        return _snr(c, iy, ix, guard)
    w = c[np.ix_(np.arange(iy - guard, iy + guard + 1) % ny, np.arange(ix - guard, ix + guard + 1) % nx)]
    n_all = c.size
    if sums is None:
        m, sd = cv2.meanStdDev(c)
        s_all = float(m[0, 0]) * n_all
        q_all = (float(sd[0, 0]) ** 2 + float(m[0, 0]) ** 2) * n_all
    else:
        s_all, q_all = sums
    w = w.astype(np.float64)
    count = n_all - w.size
    mean = (s_all - float(w.sum())) / count
    var = max((q_all - float(np.square(w).sum())) / count - mean * mean, 0.0)
    return float((c[iy, ix] - mean) / math.sqrt(var)) if var > 0 else 0.0


def _outside(c: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``c[mask]`` (row-major order) for the mask that is False on rows x cols: the rows
    outside whole, each window row without its columns."""
    keep_cols = np.ones(c.shape[1], bool)
    keep_cols[cols] = False
    in_rows = np.zeros(c.shape[0], bool)
    in_rows[rows] = True
    pieces = []
    y = 0
    for r in np.flatnonzero(in_rows):
        if r > y:
            pieces.append(c[y:r].ravel())
        pieces.append(c[r, keep_cols])
        y = r + 1
    if y < c.shape[0]:
        pieces.append(c[y:].ravel())
    return np.concatenate(pieces)


def _rotation(a: FmtImage, b: FmtImage, p: FmtParams) -> tuple[float, float, float]:
    """Steps 6-9: rotation of b relative to a in [-pi/2, pi/2) (mod pi), its SNR and the
    normalised curvature of the peak (1 / bins^2)."""
    # centro-symmetric spectrum: fold the two half turns (period 180 deg), less noise
    half = p.angles // 2
    fa, fb = _folded_spectrum(a, half), _folded_spectrum(b, half)
    cross = np.sum(fb * np.conj(fa), axis=1)  # summed over the radii: zero radial shift (no scale)
    cross /= np.maximum(np.abs(cross), 1e-30)
    import scipy.fft

    c = scipy.fft.irfft(cross, n=half, workers=1)
    i = int(np.argmax(c))
    y0, y1, y2 = c[(i - 1) % half], c[i], c[(i + 1) % half]
    den = y0 - 2 * y1 + y2
    d = 0.5 * (y0 - y2) / den if den < 0 else 0.0
    d = float(np.clip(d, -1.0, 1.0))
    curv = float(-den / max(y1, 1e-12)) if den < 0 else 0.0
    snr = _snr(c[:, None], i, 0, guard=3)
    shift = (i + d + half / 2) % half - half / 2  # bins of 360 / angles deg
    # |F_b|(w) = |F_a|(R(theta) w): b's polar rows are a's shifted by -theta
    theta = -math.radians(shift * 360.0 / p.angles)
    return theta, snr, curv


def _folded_spectrum(img: FmtImage, half: int) -> np.ndarray:
    """The rfft along the angles of the image's polar spectrum folded onto half a turn: once per
    image (kept in :attr:`FmtImage.folded`), not once per registration it is in."""
    if img.folded is None or img.folded.shape[0] != half // 2 + 1:
        import scipy.fft

        img.folded = scipy.fft.rfft(img.polar[:half] + img.polar[half:2 * half], axis=0, workers=1)
    return img.folded


def _derotate(img: np.ndarray, theta: float, interp: int = cv2.INTER_LINEAR, r0: int = 0,
              r1: int | None = None) -> np.ndarray:
    """b seen with a's axes: J(q) = b(R(theta)^T q), about the centre cell (the radar); rows r0..r1 of it."""
    n = img.shape[0]
    r1 = n if r1 is None else r1
    c, s = math.cos(theta), math.sin(theta)
    cx = cy = float(n // 2)
    # dst pixel q -> src pixel R^T (q - centre) + centre (WARP_INVERSE_MAP); from row r0
    m = np.array([[c, s, cx - c * cx - s * cy + s * r0], [-s, c, cy + s * cx - c * cy + c * r0]])
    return cv2.warpAffine(img, m, (n, r1 - r0), flags=interp + cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def _halves_spectrum(img: np.ndarray, theta: float, cols: int, pool: TaskPool | None) -> np.ndarray:
    """rfft2's first ``cols`` columns of ``img`` turned by theta (bilinear) and windowed, to float rounding, in
    two halves of rows whether on a pool's threads or one after the other (the same numbers): each half warped
    (OpenCV computes its coordinates from the half's first row: not the whole image's bits), windowed and
    transformed along its rows (``cv2.dft``, packed), then the kept columns transformed by scipy.fft on
    :func:`_workers`' threads. For the translation returned on the coarse grid, which nothing runs beside: at
    512 cells the calling thread's share 0.9 ms against 1.7-1.9 ms for the whole image's warp and transform."""
    n = img.shape[0]
    hann = _hann(img.shape)

    def half(r0: int, r1: int) -> np.ndarray:
        w = _derotate(img, theta, cv2.INTER_LINEAR, r0, r1)
        w *= hann[r0:r1]
        return _unpack_rows(cv2.dft(w, flags=cv2.DFT_ROWS), cols)

    h = n // 2
    parts = pool.map(half, [(0, h), (h, n)]) if pool is not None else [half(0, h), half(h, n)]
    import scipy.fft

    return scipy.fft.fft(np.concatenate(parts), axis=0, workers=_workers())


def _unpack_rows(ccs: np.ndarray, cols: int) -> np.ndarray:
    """The first ``cols`` columns (complex64) of each row's rfft from ``cv2.dft(..., DFT_ROWS)``'s packed rows
    of an even width n: (re 0, re 1, im 1, ..., re n/2)."""
    rows, n = ccs.shape
    h = n // 2
    out = np.empty((rows, cols), np.complex64)
    inner = min(cols, h)
    out[:, 0] = ccs[:, 0]
    if inner > 1:
        out[:, 1:inner] = ccs[:, 1:2 * inner - 1].view(np.complex64)
    if cols > h:
        out[:, h] = ccs[:, n - 1]
    return out


def register(a: FmtImage, b: FmtImage, params: FmtParams | None = None,
             prior_theta_rad: float | None = None, pool: TaskPool | None = None) -> FmtResult:
    """Steps 6-14: the pose of b's frame in a's (b's radar position and heading seen from a).

    ``prior_theta_rad`` (odometry) only breaks a tie between the two rotation candidates
    whose translation peaks are within 10 % of each other. ``pool``: threads for the
    correlations that do not depend on each other (the two candidates, each refinement step's
    two neighbours, each transform of the others on the pool's threads too); the same result, bit for
    bit, with or without."""
    with fft_workers(pool.threads if pool is not None else 1):
        return _register(a, b, params or FmtParams(), prior_theta_rad, pool)


def _register(a: FmtImage, b: FmtImage, p: FmtParams, prior_theta_rad: float | None,
              pool: TaskPool | None) -> FmtResult:
    if not (np.any(a.image) and np.any(b.image)):
        return FmtResult(0.0, 0.0, 0.0, np.diag([1e6, 1e6, 10.0]), reason="empty image")
    if pool is not None and pool.threads > 1:
        # the rotation (this thread) and what the translations need of the pair whatever the rotation
        # (another): independent, the same numbers in either order
        (theta0, snr_r, curv_r), tr = pool.map(_call, [(_rotation, a, b, p), (_translator, a, b, p, pool)])
    else:
        theta0, snr_r, curv_r = _rotation(a, b, p)
        tr = _Translator(a, b, p, pool)
    fb = tr.spectrum(theta0)
    cands = tr.translations([(theta0, fb), (theta0 + math.pi, np.conj(fb))])
    best = None
    # b turned by theta0 + pi is b turned by theta0 then by 180 deg about the centre cell, whose
    # spectrum is the conjugate (a real image), to the window's asymmetry (cv2's Hann is symmetric
    # about (n - 1) / 2, half a cell off the centre): the second candidate's translation without a
    # warp and transform of its own (the same choice of candidate and the same registrations on the
    # Oxford and RADIATE pairs; when it wins, the refinement warps around it anyway)
    for cand in cands:
        if best is None:
            best = cand
        elif prior_theta_rad is not None and abs(cand[0] - best[0]) < 0.1 * max(cand[0], best[0]):
            da = abs(math.remainder(cand[1] - prior_theta_rad, 2 * math.pi))
            db = abs(math.remainder(best[1] - prior_theta_rad, 2 * math.pi))
            best = cand if da < db else best
        elif cand[0] > best[0]:
            best = cand
    assert best is not None
    refined_curv = 0.0
    if p.refine_deg > 0:
        best, refined_curv = _refine_rotation(tr, best, math.radians(p.refine_deg))
    best = tr.final(best[1], best)
    snr_t, theta, x, y, h = best
    theta = math.remainder(theta, 2 * math.pi)
    cov = _covariance(p, snr_t, h, snr_r, curv_r, (x, y), refined_curv)
    cov[2, 2] += (p.rot_frac * theta) ** 2 + math.radians(p.rot_floor_deg) ** 2
    ok = snr_t >= p.min_snr and bool(np.all(np.isfinite(cov)))
    return FmtResult(x, y, theta, cov, snr_t, snr_r, ok, "" if ok else f"weak translation peak (SNR {snr_t:.1f})")


def register_grids(a: Grid, b: Grid, params: FmtParams | None = None, linear_power: bool = True,
                   prior_theta_rad: float | None = None) -> FmtResult:
    """Algorithm 1 on two panoramics (vehicle-frame ``Grid``): the pose of b's frame in a's.
    The function behind ``slam.FmtRegistration``; :func:`prepare` once per image and
    :func:`register` per pair when an image is registered more than once."""
    p = params or FmtParams()
    return register(prepare(a, p, linear_power), prepare(b, p, linear_power), p, prior_theta_rad)


def _call(fn: Callable[..., Any], *args: object) -> Any:
    return fn(*args)


def _translator(a: FmtImage, b: FmtImage, p: FmtParams, pool: TaskPool | None) -> _Translator:
    """:class:`_Translator` of the pair with b on the coarse grid and a's full-grid spectrum on the
    coarse rows (when the coarse grid is used): what does not depend on the rotation, ready before
    the rotation is known."""
    tr = _Translator(a, b, p, pool)
    if tr.rows is not None:
        _half(b)
        tr.fa_fine  # noqa: B018 - computed here, beside the rotation
    return tr


class _Translator:
    """Steps 10-14 for one pair: the translation of b turned by theta in a's frame.

    The older image's spectrum is computed once per image (kept in :attr:`FmtImage.spectra`), not
    once per rotation tried. On the coarse grid (:func:`_coarse_rows`: the low-pass leaves nothing
    beyond 1/4 cycle per cell), both images are first halved by ``cv2.pyrDown`` (its 5 x 5
    Gaussian keeps the aliasing of the band kept under 10 %), so each rotation tried warps and
    transforms a 4 times smaller image; the peak is still read at full resolution
    (:func:`_coarse_peak`)."""

    def __init__(self, a: FmtImage, b: FmtImage, p: FmtParams, pool: TaskPool | None = None):
        n = a.image.shape[0]
        self.p, self.n, self.a, self.b, self.pool = p, n, a, b, pool
        self._final: dict[float, tuple] = {}
        self._fa_fine: np.ndarray | None = None
        lp = _low_pass(n, p.cell_m, p.min_wavelength_m)
        self.cols, weight = _columns(a.image.shape, lp, True)
        self.rows = _coarse_rows(n, lp, self.cols) if a.image.shape[1] == n else None
        if self.rows is None:
            self.weight = weight
            self.fa = _spectrum(a, self.cols, False)
        else:
            self.weight = np.ascontiguousarray(weight[self.rows])
            self.fa = _spectrum(a, self.cols, True)

    def spectrum(self, theta: float, fine: bool = False) -> np.ndarray:
        """The spectrum (first columns of rfft2) of b turned by theta (j(q) = b(R^T q)), windowed;
        on the coarse grid, that of b halved then turned (``fine``: of b turned, the coarse rows)."""
        if fine and self.rows is not None:  # the translation returned: alone, so shared by halves of rows
            return _halves_spectrum(self.b.image, theta, self.cols, self.pool)[self.rows]
        if self.rows is None:
            return _rfft2(_derotate(self.b.image, theta) * _hann(self.b.image.shape), self.cols)
        img = _half(self.b)  # cubic: bilinear interpolation at 2 cells per wavelength of the band's top blurs it
        return _rfft2(_derotate(img, theta, cv2.INTER_CUBIC) * _hann(img.shape), self.cols)

    def translation(self, theta: float, fb: np.ndarray | None = None, fine: bool = False) -> tuple:
        """(SNR, theta, x_m, y_m, Hessian) of the translation peak at rotation theta; ``fine``: from
        the full grid's spectra (on the coarse grid: the translation :func:`register` returns)."""
        if fb is None:
            fb = self.spectrum(theta, fine)
        # j(q) = b(R^T q) = a(q + t): j is a shifted by -t; alone (not a batch's task): the whitening in halves
        pool = None if _batched() else self.pool
        if self.rows is None:
            dy, dx, snr, h = _peak(*_correlate_sums(self.fa, fb, self.weight, self.b.image.shape, pool))
        elif fine:
            dy, dx, snr, h = _coarse_peak(self.fa_fine, fb, self.weight, self.n, pool=pool)
        else:  # the search on the halved images: only the SNR is used (the translation is then final()'s)
            dy, dx, snr, h = _coarse_peak(self.fa, fb, self.weight, self.n, fit=False, pool=pool)
        return snr, theta, -dx * self.p.cell_m, -dy * self.p.cell_m, h

    def translations(self, batch: list[tuple]) -> list[tuple]:
        """:meth:`translation` of each ``(theta, fb)`` of the batch, in order (on the pool's threads:
        each is computed from this pair's images alone, so in any order, the same numbers)."""
        if self.pool is None:
            with _in_batch():
                return [self.translation(*args) for args in batch]
        return self.pool.map(self._one_thread, batch)

    def _one_thread(self, *args: object) -> tuple:
        with fft_workers(1), _in_batch():  # the batch's tasks share the threads: one each
            return self.translation(*args)  # type: ignore[arg-type]

    def final(self, theta: float, cand: tuple | None = None) -> tuple:
        """The translation returned at rotation theta: on the coarse grid, from the full grid's
        spectra (the coarse one only chooses the rotation); otherwise ``cand`` if given."""
        if self.rows is None:
            return cand if cand is not None else self.translation(theta)
        if theta not in self._final:
            self._final[theta] = self.translation(theta, fine=True)
        return self._final[theta]

    @property
    def fa_fine(self) -> np.ndarray:
        """The older image's full-grid spectrum on the coarse rows (once per pair)."""
        assert self.rows is not None
        if self._fa_fine is None:
            self._fa_fine = _spectrum(self.a, self.cols, False)[self.rows]
        return self._fa_fine


def _half(img: FmtImage) -> np.ndarray:
    """The image on the n/2 x n/2 grid (``cv2.pyrDown``: coarse cell i = fine cell 2 i, the centre kept)."""
    if img.half is None:
        img.half = cv2.pyrDown(img.image)
    return img.half


def _spectrum(a: FmtImage, cols: int, coarse: bool) -> np.ndarray:
    """rfft2 of the older image (windowed), the columns the translation uses, on the full grid or
    the coarse one: computed once per image, not once per rotation tried."""
    spectra = a.half_spectra if coarse else a.spectra
    if cols not in spectra:
        img = _half(a) if coarse else a.image
        spectra[cols] = _rfft2(img * _hann(img.shape), cols)
    return spectra[cols]


_coarse_of: dict[tuple, np.ndarray | None] = {}


def _coarse_rows(n: int, weight: np.ndarray | None, cols: int) -> np.ndarray | None:
    """Rows of the rfft2 layout (n x n image) kept on the coarse grid (:func:`_coarse_peak`):
    those of frequency |f| < 1 / (2 k) cycles / cell, k = 2 (the coarse grid of n / 2 cells of
    2 cells each), when the low-pass is 0 at every frequency beyond (None otherwise: the
    whole grid, as without a low-pass)."""
    if weight is None or n % 4:
        return None
    key = (id(weight), n, cols)
    if key not in _coarse_of:
        m = n // 2
        rows = np.r_[0:m // 2, n - m // 2:n]
        outside = np.ones(n, bool)
        outside[rows] = False
        outside[n - m // 2] = True  # the coarse grid's Nyquist row: 0 too (no aliasing of the surface's energy)
        ok = cols <= m // 2 and not np.any(weight[outside]) and not np.any(weight[:, m // 2:])
        _coarse_of[key] = rows if ok else None
    return _coarse_of[key]


def _coarse_peak(fa: np.ndarray, fb: np.ndarray, weight: np.ndarray, n: int, fit: bool = True,
                 pool: TaskPool | None = None) -> tuple[float, float, float, np.ndarray]:
    """:func:`_peak` of :func:`_correlate`'s n x n surface from the rows and columns of the
    spectra where the low-pass is not 0 (|f| < 1/4 cycle / cell on both axes), without the
    n x n surface. Why nothing is lost: the surface is the inverse transform of a spectrum
    that is 0 beyond 1/4 cycle per cell (the low-pass removes every wavelength shorter than
    min_wavelength_m >= 4 cells), so it is band-limited and its values every other cell (the
    inverse transform of the same coefficients on an n/2 x n/2 grid: Nyquist) hold all of
    it: the maximum is found on that coarse grid, then the surface's exact values on the 7 x 7
    cells around the full grid's maximum (the same sum of coefficients, evaluated at these
    cells) give the same quadratic peak and Hessian as :func:`_peak`, and its SNR's mean and
    standard deviation away from the peak come from the coarse grid's sums (the full grid's
    sum and sum of squares are 4 times theirs, Parseval on each of the 4 interleaved grids)
    less the 7 x 7 window's. The same figures to float rounding; on RADIATE turns at
    0.2 m cells, min_wavelength_m 0.8 m, 4x smaller inverse transforms and peak searches.
    ``fit`` False: the SNR alone (no sub-cell fit; the shift and Hessian returned are NaN). ``pool``: the
    whitening in halves on its threads (the same numbers)."""
    cross = _whitened(fa, fb, weight, pool)
    m = n // 2
    c, s2 = _irfft2(cross, (m, m))  # = 4 x the n x n surface every other cell
    iy, ix = np.unravel_index(int(np.argmax(c)), c.shape)
    row_k, col_k, col_w, roots = _window_freqs(n, cross.shape[1])
    spec = cross.astype(np.complex128)

    def window(y: int, x: int, r: int) -> np.ndarray:  # the n x n surface on the cells (y, x) +- r
        off = np.arange(-r, r + 1)  # exp(2 pi i k y / n) from the table of the n-th roots of unity
        return (roots[np.outer(off + y, row_k) % n] @ spec @ (roots[np.outer(col_k, off + x) % n] * col_w)).real

    y, x = 2 * int(iy), 2 * int(ix)
    w = window(y, x, 4)
    j, i = np.unravel_index(int(np.argmax(w)), w.shape)
    for _ in range(4):  # the full grid's maximum next to the coarse one's (nearly always within one cell)
        if abs(j - 4) <= 1 and abs(i - 4) <= 1:
            y, x = y + j - 4, x + i - 4
            w = w[j - 3:j + 4, i - 3:i + 4]
            break
        y, x = (y + j - 4) % n, (x + i - 4) % n
        w = window(y, x, 4)
        j, i = np.unravel_index(int(np.argmax(w)), w.shape)
    else:
        w = window(y, x, 3)
    # fit=False: the SNR only (the coarse search's)
    dy, dx, h = _quadratic_peak(w, 3, 3) if fit else (math.nan, math.nan, np.full((2, 2), math.nan))
    # the n x n surface's sum and sum of squares from its spectrum: the DC term, and Parseval (the same
    # coefficients on the n x n grid: sum c^2 = sum |X|^2 / n^2)
    s_all = float(cross[0, 0].real)
    q_all = s2 / (n * n)
    count = n * n - w.size
    mean = (s_all - float(w.sum())) / count
    var = max((q_all - float(np.square(w).sum())) / count - mean * mean, 0.0)
    sd = math.sqrt(var)
    snr = float((w[3, 3] - mean) / sd) if sd > 0 else 0.0
    sy = (y + dy + n / 2) % n - n / 2
    sx = (x + dx + n / 2) % n - n / 2
    return float(sy), float(sx), snr, h


_freqs_of: dict[tuple[int, int], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}


def _window_freqs(n: int, cols: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_coarse_peak`'s kept rows' and columns' frequencies (cycles per n cells), the columns'
    weights (Hermitian half: twice each column but DC; 1 / n^2 of the inverse DFT) and the n-th roots of
    unity exp(2 pi i j / n) (a table: no complex exponential per coefficient and window)."""
    if (n, cols) not in _freqs_of:
        m = n // 2
        _freqs_of[n, cols] = (np.r_[0:m // 2, -(m // 2):0], np.arange(cols),
                              (np.where(np.arange(cols) == 0, 1.0, 2.0) / (n * n))[:, None],
                              np.exp(np.arange(n) * (2j * np.pi / n)))
    return _freqs_of[n, cols]


def _refine_rotation(tr: _Translator, best: tuple, step: float) -> tuple[tuple, float]:
    """Beyond Algorithm 1: the rotation of the spectra is good to a bin; the translation
    peak's SNR as a function of the rotation is sharper. Parabola through theta - step,
    theta, theta + step (moving at most twice towards the larger side), then the translation
    again at the refined rotation. Also returns the parabola's curvature -d2 SNR / d theta2
    (1 / rad^2; 0 when there is no maximum): the rotation's covariance."""
    theta = best[1]
    mid = best
    done = {theta: best}  # a step back onto a rotation already tried (exactly) is not computed again

    def at(t: float) -> tuple:
        if t not in done:
            done[t] = tr.translation(t)
        return done[t]

    for _ in range(3):
        todo = [t for t in (theta - step, theta + step) if t not in done]
        if len(todo) == 2:  # both neighbours at once, a batch (on the pool's threads if any)
            done.update(zip(todo, tr.translations([(t,) for t in todo]), strict=True))
        lo = at(theta - step)
        hi = at(theta + step)
        if lo[0] > mid[0] and lo[0] >= hi[0]:
            theta, mid = theta - step, lo
            continue
        if hi[0] > mid[0]:
            theta, mid = theta + step, hi
            continue
        den = lo[0] - 2 * mid[0] + hi[0]
        if den >= 0:
            return mid, 0.0
        d = float(np.clip(0.5 * (lo[0] - hi[0]) / den, -0.5, 0.5))
        return tr.final(theta + d * step), -den / step ** 2
    return mid, 0.0


def _covariance(p: FmtParams, snr_t: float, h: np.ndarray, snr_r: float, curv_r: float,
                t_xy: tuple[float, float], refined_curv: float = 0.0) -> np.ndarray:
    """var = k / (SNR^2 H) + floor^2 per peak ((y, x) Hessian -> (x, y) covariance), plus
    the along-track term; the refined rotation's var = k / (SNR c), c = -d2 SNR / d theta2
    (the same form: H = c / SNR)."""
    cov = np.zeros((3, 3))
    floor = p.floor_cells ** 2
    snr_t = max(snr_t, 1.0)
    hxy = np.array([[h[1, 1], h[0, 1]], [h[1, 0], h[0, 0]]])  # to (x, y) order
    w, v = np.linalg.eigh(0.5 * (hxy + hxy.T))
    w = np.maximum(w, 0.05)  # a flat direction: at most 20 cells^2 / (k / SNR^2)
    cxy = (v / w) @ v.T * (p.k_translation / snr_t ** 2) + np.eye(2) * floor
    cov[:2, :2] = cxy * p.cell_m ** 2
    if p.along_frac > 0 and math.hypot(*t_xy) > 0:
        u = np.asarray(t_xy) / math.hypot(*t_xy)
        cov[:2, :2] += np.outer(u, u) * (p.along_frac * math.hypot(*t_xy)) ** 2
    bin_rad = 2 * math.pi / p.angles
    if refined_curv > 0:
        cov[2, 2] = p.k_rotation_refined / (snr_t * refined_curv) + floor * bin_rad ** 2
    else:
        curv = max(curv_r, 0.05)
        cov[2, 2] = (p.k_rotation / max(snr_r, 1.0) ** 2 / curv + floor) * bin_rad ** 2
    return cov
