"""The FMT's 2-D transforms (:mod:`impala_slam.fmt.core`'s docstring, "Transforms" and "Sixth round"):
``cv2.dft``'s on the calling thread, the packed spectra unpacked; scipy.fft's on :func:`fft_workers`' threads
for the columns of a transform whose rows were done by halves, and for odd sides; the 2-D Hann window."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager

import cv2
import numpy as np

__all__ = ["fft_workers"]


_windows: dict[tuple[int, int], np.ndarray] = {}


def hann_window(shape: tuple[int, int]) -> np.ndarray:
    if shape not in _windows:
        _windows[shape] = cv2.createHanningWindow((shape[1], shape[0]), cv2.CV_32F)
    return _windows[shape]


_local = threading.local()


def current_workers() -> int:
    """scipy.fft's threads for this thread's transforms (:func:`fft_workers`; 1 by default). pocketfft shares
    a batch of 1-D transforms between them, each computed alike: the same numbers with any number."""
    return getattr(_local, "workers", 1)


@contextmanager
def fft_workers(n: int) -> Iterator[None]:
    """This thread's transforms on ``n`` threads within the block (:func:`current_workers`)."""
    old = current_workers()
    _local.workers = n
    try:
        yield
    finally:
        _local.workers = old


def _even(shape: tuple[int, ...]) -> bool:
    """An image OpenCV's packed spectrum (CCS) is laid out for here: 2-D, both sides even."""
    return len(shape) == 2 and shape[0] % 2 == 0 and shape[1] % 2 == 0 and min(shape) >= 4


def rfft2_first(img: np.ndarray, cols: int) -> np.ndarray:
    """``scipy.fft.rfft2(img)``'s first ``cols`` columns, to float rounding: for a float32 image of even sides,
    ``cv2.dft``'s packed spectrum (CCS) unpacked to rfft2's layout on this thread (1.3-2.2 x faster than scipy.fft's
    on one thread at 256-512 cells, the unpacking included, and as fast as scipy.fft's on two; the same sums to
    float32 rounding, 1e-7 of the largest coefficient); otherwise scipy.fft's on
    :func:`current_workers`' threads: the real transform of the rows then the transform of the kept columns."""
    if img.dtype == np.float32 and _even(img.shape):
        return _unpack_ccs(cv2.dft(img), cols)
    import scipy.fft

    if cols >= img.shape[1] // 2 + 1:
        return scipy.fft.rfft2(img, workers=current_workers())
    w = current_workers()
    return scipy.fft.fft(scipy.fft.rfft(img, axis=1, workers=w)[:, :cols], axis=0, workers=w)


def rows_then_columns(img: np.ndarray, cols: int) -> np.ndarray:
    """``scipy.fft.rfft2(img)``'s first ``cols`` columns (complex64), to float32 rounding, as
    :func:`impala_slam.fmt.spectra.prepare` computes them by halves of rows: for an even width, ``cv2.dft``'s
    transform of the rows in float32 (3 x faster than scipy.fft's at 512 x 512 on one thread), unpacked, then
    :func:`columns_fft`; otherwise :func:`rfft2_first`'s scipy.fft."""
    if img.ndim != 2 or img.shape[1] % 2 or img.shape[1] < 4:
        return rfft2_first(img, cols)  # not OpenCV's layout: scipy.fft's
    return columns_fft(rows_fft(np.ascontiguousarray(img, np.float32), cols))


def rows_fft(img: np.ndarray, cols: int) -> np.ndarray:
    """Each row's rfft, its first ``cols`` columns (complex64): ``cv2.dft``'s transform of the rows of a float32
    image of even width, unpacked (:func:`unpack_rows`). Each row is computed alike in any batch of rows, so a
    transform done by halves of rows gives the whole image's numbers (the first step of
    :func:`rows_then_columns`, of the prepared image's spectrum and of the translation returned's)."""
    return unpack_rows(cv2.dft(img, flags=cv2.DFT_ROWS), cols)


def columns_fft(rows: np.ndarray) -> np.ndarray:
    """``scipy.fft.fft(rows, axis=0)`` on :func:`current_workers`' threads: the second step of a 2-D transform
    whose rows were transformed by halves (:func:`rfft2_first`'s, with the first step elsewhere; each column
    computed alike whatever the threads: the same numbers). (By halves of the columns on a pool's threads, the
    fifth round's, it took 1.35 ms against 0.79 ms on one thread at 512 x 130 on a loaded host.)"""
    import scipy.fft

    return scipy.fft.fft(rows, axis=0, workers=current_workers())


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


def irfft2_sums(spec: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, float]:
    """``scipy.fft.irfft2(spec, s=shape)`` (the columns of ``spec`` beyond its own are 0), to float rounding,
    and the sum of |X|^2 over the whole (Hermitian) spectrum: Parseval, the surface's sum of squares times its
    size. For complex64 and even sides, ``cv2.dft``'s real inverse of the packed spectrum (CCS) on this thread
    (0.52 ms at 256 x 256 against 1.22 ms for scipy.fft's on two threads, 1.58 against 2.80 ms at 400 x 400, on a
    loaded host; as fast when the cores are idle); otherwise scipy.fft's, the inverse of the columns then the real
    inverse of the rows."""
    if spec.dtype == np.complex64 and _even(shape) and spec.shape[1] <= shape[1] // 2 + 1:
        from ._jit import pack_ccs

        ccs = np.empty(shape, np.float32)
        s2 = pack_ccs(np.ascontiguousarray(spec), ccs)
        return cv2.dft(ccs, flags=cv2.DFT_INVERSE | cv2.DFT_REAL_OUTPUT | cv2.DFT_SCALE), s2
    import scipy.fft

    from ._jit import sum_sq

    w = current_workers()
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


def unpack_rows(ccs: np.ndarray, cols: int) -> np.ndarray:
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
