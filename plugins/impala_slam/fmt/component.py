"""``slam.FmtRegistration``: consecutive radar images registered by the Fourier-Mellin
transform (seed 2, Algorithm 1; the function is :func:`impala_slam.fmt.core.register`).

Each image is registered with the previous one. Outputs, stamped with the newer image:
``transform``, the newer image's pose in the older one's frame with the covariance of the
correlation peaks (``RelativePose2D``: from = the older image's time, kind
``registration``, or ``failed`` when the translation peak is too weak, its covariance
then the huge one of an unknown transform); the first image, which has no predecessor,
gives the identity from itself to itself (kind ``start``), so a consumer synchronised on
images and transforms sees one transform per image. ``pose`` chains the transforms from
the first image (frame ``fmt``): registration-only odometry, the per-pair errors of which
the trajectory evaluator measures. Its summary gives the wall time per image (``fmt_ms``,
mean) and the CPU time (``fmt_cpu_ms``, this thread's and the pool's, median of the last 4096
images; with ``threads`` > 1 the helper threads of scipy.fft are not in it: bench/fmt_ekf.py
measures the CPU on one thread). ``threads`` (default 2): the registration's independent correlations run on that
many threads (:class:`impala_slam.fmt.parallel.TaskPool`), and so do the preparation's
element-wise steps (two halves of rows), its polar spectrum beside the spectrum the next pair needs, and the
translation returned's warp (two halves of rows); steps under a millisecond stay on the calling thread (a
hand-off cost 0.3-0.7 ms on a loaded 2-core VM); the results are the same bits with 1 or 2, the wall time
lower on idle cores.
"""

from __future__ import annotations

import math
import time
from collections import deque

import numpy as np

from impala_flow import Component, Input, Output, Param
from impala_flow.msgs import Grid, Pose2D, RelativePose2D

from ..se2 import compose
from .core import FmtImage, FmtParams, prepare, register, warm_up
from .parallel import TaskPool

__all__ = ["FmtRegistration", "FmtComponent", "UNKNOWN_COV"]

#: covariance given to a failed registration (no information)
UNKNOWN_COV = np.diag([1e4, 1e4, (2 * math.pi) ** 2])


class FmtComponent(Component):
    """Base of the components that register images by FMT: its parameters."""

    cell_m = Param(float, default=0.5, gt=0, doc="cell of the registration grid (m)")
    size = Param(int, default=400, ge=32, doc="cells per side of the registration grid")
    range_min_m = Param(float, default=3.0, ge=0, doc="blind range, zeroed before registering")
    range_max_m = Param(float, default=0.0, ge=0, doc="outer radius used (0: half the grid side)")
    taper_m = Param(float, default=15.0, ge=0, doc="radial cosine taper inside range_max_m")
    threshold_quantile = Param(float, default=0.9, ge=0, lt=1,
                               doc="step 2: cells under this quantile of the observed power are zeroed")
    angles = Param(int, default=720, ge=90, doc="rows of the polar spectrum over 360 deg (rotation bins)")
    refine_deg = Param(float, default=0.5, ge=0,
                       doc="rotation refined on the translation peak by steps of this (0: Algorithm 1 as written)")
    along_frac = Param(float, default=0.01, ge=0,
                       doc="covariance: std along the translation per metre (odometer scale in the images)")
    rot_frac = Param(float, default=0.02, ge=0, doc="covariance: rotation std per radian turned")
    rot_floor_deg = Param(float, default=0.05, ge=0, doc="covariance: rotation std the peaks never see")
    min_snr = Param(float, default=6.0, gt=0, doc="translation peak SNR under which a registration fails")
    min_wavelength_m = Param(float, default=0.0, ge=0,
                             doc="finest spatial wavelength in the translation correlation (m; 0: up to the grid's "
                                 "Nyquist): the sensor's resolution at the outer range, 2 pi range_max_m / azimuths")
    linear_power = Param(bool, default=True, doc="the images hold power (False: already in dB)")

    def fmt_params(self) -> FmtParams:
        return FmtParams(cell_m=self.cell_m, size=self.size, range_min_m=self.range_min_m,
                         range_max_m=self.range_max_m, taper_m=self.taper_m,
                         db_floor_quantile=self.threshold_quantile, min_snr=self.min_snr,
                         angles=self.angles, refine_deg=self.refine_deg,
                         along_frac=self.along_frac, rot_frac=self.rot_frac, rot_floor_deg=self.rot_floor_deg,
                         min_wavelength_m=self.min_wavelength_m)


class FmtRegistration(FmtComponent):
    """Registers each radar image with the previous one by the Fourier-Mellin transform."""

    image = Input(Grid, doc="panoramic image in the vehicle frame (radar.PanoramicBuilder / SpeckleFilter)")
    transform = Output(RelativePose2D, doc="this image's pose in the previous image's frame, with covariance")
    pose = Output(Pose2D, doc="the registrations chained from the first image (frame fmt)")
    threads = Param(int, default=2, ge=1, le=4,
                    doc="threads of a registration's independent correlations (the two rotation candidates, "
                        "the refinement's two neighbours), of its image's preparation by halves of rows and of "
                        "that preparation's column transforms (scipy.fft workers): the same results with any "
                        "number, less wall time")

    def start(self) -> None:
        self.params_fmt = self.fmt_params()
        self._pool = TaskPool(self.threads)
        warm_up()  # the compiled loop loaded here, not in the first turn
        self._prev: tuple[int, FmtImage] | None = None
        self._chain = (0.0, 0.0, 0.0)
        self.images = 0
        self.failures = 0
        self.fmt_s = 0.0
        self.cpu_ms: deque[float] = deque(maxlen=4096)  # CPU time of the last images (this thread's)

    def process(self, t: int) -> None:
        grid: Grid = self.image.take()
        t0, c0, w0 = time.perf_counter(), time.thread_time(), self._pool.cpu_s
        cur = prepare(grid, self.params_fmt, self.linear_power, workers=self._pool.threads, pool=self._pool)
        self.images += 1
        if self._prev is None:
            self.fmt_s += time.perf_counter() - t0
            self.cpu_ms.append(1e3 * (time.thread_time() - c0 + self._pool.cpu_s - w0))
            self._prev = (t, cur)
            self.transform.emit(t, RelativePose2D(t, t, 0.0, 0.0, 0.0, np.zeros((3, 3)), "start"))
            self.pose.emit(t, Pose2D(0.0, 0.0, 0.0, np.zeros((3, 3)), "fmt"))
            return
        t_prev, prev = self._prev
        r = register(prev, cur, self.params_fmt, pool=self._pool)
        self.fmt_s += time.perf_counter() - t0
        self.cpu_ms.append(1e3 * (time.thread_time() - c0 + self._pool.cpu_s - w0))
        self._prev = (t, cur)
        if not r.ok:
            self.failures += 1
            self.log.debug("registration %d -> %d failed: %s", t_prev, t, r.reason)
            self.transform.emit(t, RelativePose2D(t_prev, t, 0.0, 0.0, 0.0, UNKNOWN_COV.copy(), "failed"))
            return
        self.transform.emit(t, RelativePose2D(t_prev, t, r.x_m, r.y_m, r.theta_rad, r.cov_xyt, "registration"))
        self._chain = compose(self._chain, r.xyt)
        self.pose.emit(t, Pose2D(*self._chain, np.zeros((3, 3)), "fmt"))

    def stop(self) -> None:
        if getattr(self, "_pool", None) is not None:
            self._pool.close()

    def summary(self) -> dict:
        if not getattr(self, "images", 0):
            return {}
        # fmt_ms: wall time per image (mean); fmt_cpu_ms: CPU time per image, median of the last 4096
        return {"images": self.images, "failures": self.failures,
                "fmt_ms": round(1e3 * self.fmt_s / self.images, 2),
                "fmt_cpu_ms": round(float(np.median(self.cpu_ms)), 2)}
