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
  search) and only the 7 x 7 cells around the peak at full resolution (:func:`coarse_peak`;
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
surface; :func:`coarse_peak`'s window from a table of the roots of unity; on the coarse grid an image's
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
the same thread; the whitenings nothing runs beside in two halves of rows when their spectrum holds 256 KiB or
more (numpy's temporary elision, which decides how fb * conj(fa) is rounded, made explicit; 0-0.1 ms); the
polar spectrum's ``cv2.warpPolar`` as its own ``cv2.remap`` from maps computed once (0.34 against 0.47 ms at 512
cells), by halves of the angles on the pool; the windowed image only on the path that transforms it. The
calling thread's CPU per registration on 2 threads, median, the code before and after alternating on the same
60 RADIATE and 40 campus turns (load 1.3-2): with OpenCV on one thread (bench/speed.py's) RADIATE 12.85 -> 12.37
ms, campus 12.42 -> 11.91 ms; with OpenCV on 2 (a graph run's, whose own threads already shared the whole warp)
RADIATE 12.28 -> 11.90 ms, campus 12.35 -> 12.41.
The threshold's quantile (fourth round, third part), the same numbers as np.quantile: each half of rows selects,
after its warp and on its own thread, its values over a bound taken on a sample of its own (stride 61: a stride of
64 sampled the same few columns of every row, and on RADIATE one half's bound lay over the whole image's quantile),
and the calling thread partitions only a window of those around the two order statistics (from a sample of them):
its share 0.90 -> 0.40 ms at 512 cells, 0.63 -> 0.28 ms at 400. The calling thread's CPU per registration on 2
threads (OpenCV on 1), median, the code before and after alternating on the same 60 RADIATE and 40 campus turns three
times (load 1.4-5): RADIATE 12.18 -> 11.80 ms, campus 12.95 -> 12.56 ms; one thread 19.61 -> 19.42, 19.92 -> 19.50.
Measured and left: (1) the coarse search's de-rotation bilinear instead of bicubic (3.4 x cheaper at 256 cells:
-1.2 ms on the calling thread, -1.8 ms on one): the RADIATE head's FMT ATE 3.7094 -> 3.2040 m and 3 of 4 campus
seeds on the coarse grid (min_wavelength_m 2 m) better, but Oxford's pairs' rotation 0.0833 -> 0.1020 deg and ATE
0.0871 -> 0.0880 m: bilinear's blur depends on the rotation's fractional offsets and biases the refinement's
parabola, as this module said. (2) The spectra nothing runs beside (the first candidate's, a lone refinement
step's, the last) in halves of rows on the pool like the translation returned: accuracy equal to the micrometre
(the 6 campus seeds' ATE summed -3 um, RADIATE FMT -6 um, fmt_ekf_navtech +5 um), the calling thread -0.2 ms
with OpenCV on one thread but +0.1 to +0.5 ms with OpenCV on 2 and no lower wall: not kept.

One hand-off less (fifth round): with a pool, the refinement's first two rotations (theta0 -+ refine_deg) are
computed on one thread while the other computes theta0's spectrum and both candidates' translations (one batch
where there were a lone transform and two batches of two); theta0's candidate nearly always wins and the
refinement starts from those two (when theta0 + pi wins they are not used). Each translation is computed as its
batch computed it: the same bits (every registration of 59 RADIATE and 39 campus turns, 1 and 2 threads). FMT's
wall time per turn in graphs/oxford.yaml, median over the 400 RADIATE turns, the code before and after
alternating on a quiet machine: 16.04 / 16.32 -> 15.34 / 15.04 ms; on a campus-open mission 15.44 / 14.94 ->
14.32 / 14.55 ms.

Sixth round: the calling thread's serial steps. Whether an image has a cell not 0 (:attr:`FmtImage.any_cell`, two
``np.any`` over 512 x 512 cells per registration) is taken by :func:`prepare`'s halves of rows, once per image; the
threshold's order statistics are selected among each half's values over its own bound, as they are (not selected
again over the larger bound; exact whenever the lower one lies over both bounds, numpy's selection otherwise): the
same bits. :func:`coarse_peak`'s 9 x 9 window of the surface is summed in complex64, as the spectrum is, not in a
complex128 copy (0.5 ms a call on the calling thread at 512 cells, 3.2 calls a turn): the registrations of 59
RADIATE turns move by at most 3 um and 2e-6 deg, the campus ones (no coarse grid) not at all; the RADIATE head's FMT
ATE through graphs/oxford.yaml 3.7104210 -> 3.7104163 m, its pairs 9.623543 -> 9.623556 cm and 0.6636176 ->
0.6636175 deg; Oxford's ATE 0.0870513 -> 0.0870515 m, its pairs 5.795947 -> 5.795951 cm and 0.0832799 -> 0.0832799
deg. Wall time per registration with its image's preparation (2 threads, the same 60 RADIATE turns, the code before
and after alternating 8 times on a host running 50-60 % slower than in the fifth round): median 23.61 -> 22.67 ms,
the process's CPU 35.5 -> 34.1 ms.

Fewer hand-offs (sixth round, second part). On a loaded 2-core VM a hand-off to the other thread cost 0.3-0.7 ms
(the other virtual CPU had to be woken), against 35 us on an idle one, so the steps under a millisecond stay on the
calling thread, which supersedes the rules of "Threads" and "Transforms" above: every 2-D transform of an image of
even sides is ``cv2.dft``'s on the thread that needs it (the inverse at 256 x 256 0.52 ms against 1.22 ms for
scipy.fft's on two threads, 1.58 against 2.80 ms at 400 x 400, loaded; as fast when the cores are idle); a whitening
outside the batches is done whole (0.28 against 0.97 ms in halves at 256 x 128); register's scipy.fft transforms
(the translation returned's columns) run on one thread (0.79 against 1.05 ms on two, 1.35 ms by halves on the
pool). What stays on the pool takes a millisecond or more a task: the candidates and the refinement's pairs, the
preparation's warp, threshold and window by halves, the translation returned's warp and row transforms by halves
(without those halves, +1 ms a turn). The rotation and the pair's set-up run on the calling thread, the image's
folded polar spectrum having been computed in prepare beside its coarse spectrum. The transforms that moved from
scipy.fft to cv2.dft sum in another order (float32 rounding): the registrations of 59 RADIATE and 39 campus turns
move by at most 1.8 um and 1.5e-6 deg, the same with 1 thread or 2; the RADIATE head's FMT ATE through
graphs/oxford.yaml 3.7104163 -> 3.7104195 m, its pairs 9.623556 -> 9.623555 cm; Oxford's ATE 0.0870515 -> 0.0870514
m; graphs/fmt_ekf_navtech.yaml on the RADIATE head EKF / iSAM2 / LM 1.0098277 / 1.0095174 / 1.0095222 ->
1.0098289 / 1.0095186 / 1.0095233 m; campus-open 60 s seeds 29, 31, 41, 13, 47, 53 FMT ATE summed 2.1341981 ->
2.1341982 m. Wall per registration with its preparation, in-process A/B (both trees loaded in one process, turns
interleaved, order alternating; a control of one tree against itself within 0.2 ms), loaded host: RADIATE -0.77 ms
median per turn (77 % of 354 turns faster), campus -2.2 to -3.0 ms (73-75 % of 156).

Seventh round: the preparation's CPU. Measured on a quiet host (a fixed warp timing 0.67 ms against 0.73 in the
fifth round's quiet hour), the sixth round's tree ran FMT through graphs/oxford.yaml at 16.3 ms a turn and on campus
at 16.5: the hand-offs it removed cost little on an idle host, and in a graph the other components hold the second
core, so a registration's wall time follows its CPU. The threshold, dB and taper are now two compiled passes around
numpy's logarithm of the cells kept, one listing them, the other writing their tapered dB back (the same bits as
numpy's formula; 0.45 against 1.1 ms at 512 cells), and the windowed image's row transform is ``cv2.dft``'s (0.33
against 1.03 ms for scipy.fft's at 512 x 512), also when :func:`polar_spectrum` transforms an image itself
(:func:`~impala_slam.fmt.transforms.rows_then_columns`). CPU per registration with its preparation on one thread,
in-process A/B both orders: RADIATE -1.13 / -1.12 ms, campus -0.8 ms; on 2 threads the wall -0.85 ms. The rows'
transform sums in another order (float32 rounding): the RADIATE head's FMT ATE through graphs/oxford.yaml 3.7104195
-> 3.7104283 m, its pairs 9.623555 -> 9.623544 cm and 0.6636176 deg; Oxford's ATE 0.0870514 -> 0.0870513 m, its
pairs 5.795946 -> 5.795938 cm; campus-open 60 s seeds 29, 31, 41, 13, 47, 53 FMT ATE summed 2.1341982 -> 2.1341996
m. Tried and not kept: the coarse search's bicubic rotation as three shears of 1-D cubic passes (Unser's; compiled):
1.9 against 1.1 ms at 256 cells and, on a synthetic pattern, a mean error of 0.035 against OpenCV's 0.021 (the x
passes blur twice); the preparation's quarter-cell shift as a compiled bilinear pass: 0.91 against OpenCV's 0.51 ms
a half; the observed values gathered by a compiled pass: 0.37 against numpy's mask and selection's 0.32 ms a half;
without a coarse grid (campus), the translation returned warped and its rows transformed by halves of rows on the
pool as on the coarse grid: +0.3 to +0.8 ms a turn (in-process A/B, loaded); a 0.5 ms GIL switch interval in the
graph run: FMT's median unchanged.

Where the code is: :mod:`impala_slam.fmt.params` (FmtParams, FmtImage, FmtResult), :mod:`impala_slam.fmt.spectra`
(the preparation, steps 1-5, and an image's spectra), :mod:`impala_slam.fmt.correlation` (the phase correlation,
its peak, Hessian and SNR), :mod:`impala_slam.fmt.transforms` (the 2-D transforms, the Hann window), this module
(the rotation, the translation at each rotation tried, the refinement, the covariance: the registration).

I deliberately compute the correlation surfaces with scipy.fft and cv2.dft instead of calling
``cv2.phaseCorrelate``: it returns only the peak, and the covariance needs the surface.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from impala_flow.msgs import Grid

from .correlation import (
    coarse_peak,
    coarse_rows,
    correlate_sums,
    masked_snr,
    phase_correlation,
    spectrum_columns,
    surface_peak,
)
from .parallel import TaskPool
from .params import FmtImage, FmtParams, FmtResult
from .spectra import (
    call_with,
    folded_spectrum,
    half_image,
    image_spectrum,
    low_pass,
    polar_spectrum,
    prepare,
    warm_up,
)
from .transforms import columns_fft, fft_workers, hann_window, rfft2_first, rows_fft

__all__ = ["FmtParams", "FmtImage", "FmtResult", "prepare", "polar_spectrum", "register", "register_grids",
           "phase_correlation", "warm_up"]


def _rotation(a: FmtImage, b: FmtImage, p: FmtParams) -> tuple[float, float, float]:
    """Steps 6-9: rotation of b relative to a in [-pi/2, pi/2) (mod pi), its SNR and the
    normalised curvature of the peak (1 / bins^2)."""
    # centro-symmetric spectrum: fold the two half turns (period 180 deg), less noise
    half = p.angles // 2
    fa, fb = folded_spectrum(a, half), folded_spectrum(b, half)
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
    snr = masked_snr(c[:, None], i, 0, guard=3)
    shift = (i + d + half / 2) % half - half / 2  # bins of 360 / angles deg
    # |F_b|(w) = |F_a|(R(theta) w): b's polar rows are a's shifted by -theta
    theta = -math.radians(shift * 360.0 / p.angles)
    return theta, snr, curv


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
    :func:`current_workers`' threads (:func:`columns_fft`). For the translation returned on the coarse grid,
    which nothing runs beside: at 512 cells the calling thread's share 0.9 ms against 1.7-1.9 ms for the whole
    image's warp and transform."""
    n = img.shape[0]
    hann = hann_window(img.shape)

    def half(r0: int, r1: int) -> np.ndarray:
        w = _derotate(img, theta, cv2.INTER_LINEAR, r0, r1)
        w *= hann[r0:r1]
        return rows_fft(w, cols)

    h = n // 2
    parts = pool.map(half, [(0, h), (h, n)]) if pool is not None else [half(0, h), half(h, n)]
    return columns_fft(np.concatenate(parts))  # scipy.fft's, on this thread (register's fft_workers(1))


def register(a: FmtImage, b: FmtImage, params: FmtParams | None = None,
             prior_theta_rad: float | None = None, pool: TaskPool | None = None) -> FmtResult:
    """Steps 6-14: the pose of b's frame in a's (b's radar position and heading seen from a).

    ``prior_theta_rad`` (odometry) only breaks a tie between the two rotation candidates
    whose translation peaks are within 10 % of each other. ``pool``: threads for the
    correlations that do not depend on each other (the two candidates, each refinement step's
    two neighbours) and for the translation returned's warp and row transforms by halves of rows; the other
    steps, under a millisecond each, on this thread; the same result, bit for bit, with or without."""
    with fft_workers(1):
        return _register(a, b, params or FmtParams(), prior_theta_rad, pool)


def _register(a: FmtImage, b: FmtImage, p: FmtParams, prior_theta_rad: float | None,
              pool: TaskPool | None) -> FmtResult:
    if not (a.any_cell and b.any_cell):
        return FmtResult(0.0, 0.0, 0.0, np.diag([1e6, 1e6, 10.0]), reason="empty image")
    # the rotation, then what the translations need of the pair whatever the rotation: from prepare()'s images both
    # are ready but for a few products (the spectra, halved images and folded polar spectra computed there, beside
    # each other), so on this thread (a hand-off to another would cost what it saves)
    theta0, snr_r, curv_r = _rotation(a, b, p)
    tr = _translator(a, b, p, pool)
    step = math.radians(p.refine_deg)
    first: dict[float, tuple] = {}
    if p.refine_deg > 0 and pool is not None and pool.threads > 1:
        # the refinement's first rotations (theta0 -+ step: theta0's candidate nearly always wins) on one thread
        # while the other computes theta0's spectrum and both candidates: one hand-off instead of a lone
        # transform and two batches of two; each translation computed as its batch would (the same numbers),
        # the two neighbours unused when theta0 + pi wins
        cands, near = pool.map(call_with, [(tr.candidates, theta0, True),
                                           (tr.in_turn, [(theta0 - step,), (theta0 + step,)])])
        first = dict(zip((theta0 - step, theta0 + step), near, strict=True))
    else:
        cands = tr.candidates(theta0)
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
        best, refined_curv = _refine_rotation(tr, best, step, first if best[1] == theta0 else None)
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


def _translator(a: FmtImage, b: FmtImage, p: FmtParams, pool: TaskPool | None) -> _Translator:
    """:class:`_Translator` of the pair with b on the coarse grid (when the coarse grid is used; prepare() has
    halved it already): halved here, not by both threads of the first batch at once."""
    tr = _Translator(a, b, p, pool)
    if tr.rows is not None:
        half_image(b)
    return tr


class _Translator:
    """Steps 10-14 for one pair: the translation of b turned by theta in a's frame.

    The older image's spectrum is computed once per image (kept in :attr:`FmtImage.spectra`), not
    once per rotation tried. On the coarse grid (:func:`coarse_rows`: the low-pass leaves nothing
    beyond 1/4 cycle per cell), both images are first halved by ``cv2.pyrDown`` (its 5 x 5
    Gaussian keeps the aliasing of the band kept under 10 %), so each rotation tried warps and
    transforms a 4 times smaller image; the peak is still read at full resolution
    (:func:`coarse_peak`)."""

    def __init__(self, a: FmtImage, b: FmtImage, p: FmtParams, pool: TaskPool | None = None):
        n = a.image.shape[0]
        self.p, self.n, self.a, self.b, self.pool = p, n, a, b, pool
        self._final: dict[float, tuple] = {}
        self._fa_fine: np.ndarray | None = None
        lp = low_pass(n, p.cell_m, p.min_wavelength_m)
        self.cols, weight = spectrum_columns(a.image.shape, lp, True)
        self.rows = coarse_rows(n, lp, self.cols) if a.image.shape[1] == n else None
        if self.rows is None:
            self.weight = weight
            self.fa = image_spectrum(a, self.cols, False)
        else:
            self.weight = np.ascontiguousarray(weight[self.rows])
            self.fa = image_spectrum(a, self.cols, True)

    def spectrum(self, theta: float, fine: bool = False) -> np.ndarray:
        """The spectrum (first columns of rfft2) of b turned by theta (j(q) = b(R^T q)), windowed;
        on the coarse grid, that of b halved then turned (``fine``: of b turned, the coarse rows)."""
        if fine and self.rows is not None:  # the translation returned: alone, so shared by halves of rows
            return _halves_spectrum(self.b.image, theta, self.cols, self.pool)[self.rows]
        if self.rows is None:
            return rfft2_first(_derotate(self.b.image, theta) * hann_window(self.b.image.shape), self.cols)
        img = half_image(self.b)  # cubic: bilinear interpolation at 2 cells per wavelength of the band's top blurs it
        return rfft2_first(_derotate(img, theta, cv2.INTER_CUBIC) * hann_window(img.shape), self.cols)

    def translation(self, theta: float, fb: np.ndarray | None = None, fine: bool = False) -> tuple:
        """(SNR, theta, x_m, y_m, Hessian) of the translation peak at rotation theta; ``fine``: from
        the full grid's spectra (on the coarse grid: the translation :func:`register` returns)."""
        if fb is None:
            fb = self.spectrum(theta, fine)
        # j(q) = b(R^T q) = a(q + t): j is a shifted by -t
        if self.rows is None:
            dy, dx, snr, h = surface_peak(*correlate_sums(self.fa, fb, self.weight, self.b.image.shape))
        elif fine:
            dy, dx, snr, h = coarse_peak(self.fa_fine, fb, self.weight, self.n)
        else:  # the search on the halved images: only the SNR is used (the translation is then final()'s)
            dy, dx, snr, h = coarse_peak(self.fa, fb, self.weight, self.n, fit=False)
        return snr, theta, -dx * self.p.cell_m, -dy * self.p.cell_m, h

    def candidates(self, theta: float, beside: bool = False) -> list[tuple]:
        """The two candidates' translations, theta and theta + pi (the second from the first's spectrum, conjugated:
        no warp nor transform of its own): the spectrum on this thread, the two translations as a batch
        (:meth:`translations`). ``beside``: a task beside another on the pool's threads: the two one after the
        other on this thread (:meth:`in_turn`, the same numbers)."""
        fb = self.spectrum(theta)
        batch = [(theta, fb), (theta + math.pi, np.conj(fb))]
        return self.in_turn(batch) if beside else self.translations(batch)

    def in_turn(self, batch: list[tuple]) -> list[tuple]:
        """:meth:`translation` of each of the batch one after the other on this thread (the same numbers as
        :meth:`translations`)."""
        return [self.translation(*args) for args in batch]

    def translations(self, batch: list[tuple]) -> list[tuple]:
        """:meth:`translation` of each ``(theta, fb)`` of the batch, in order (on the pool's threads:
        each is computed from this pair's images alone, so in any order, the same numbers)."""
        if self.pool is None:
            return self.in_turn(batch)
        return self.pool.map(self.translation, batch)

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
            self._fa_fine = image_spectrum(self.a, self.cols, False)[self.rows]
        return self._fa_fine


def _refine_rotation(tr: _Translator, best: tuple, step: float, first: dict[float, tuple] | None = None
                     ) -> tuple[tuple, float]:
    """Beyond Algorithm 1: the rotation of the spectra is good to a bin; the translation
    peak's SNR as a function of the rotation is sharper. Parabola through theta - step,
    theta, theta + step (moving at most twice towards the larger side), then the translation
    again at the refined rotation. Also returns the parabola's curvature -d2 SNR / d theta2
    (1 / rad^2; 0 when there is no maximum): the rotation's covariance."""
    theta = best[1]
    mid = best
    done = {theta: best}  # a step back onto a rotation already tried (exactly) is not computed again
    done.update(first or {})  # the first neighbours, when computed beside the candidates

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
