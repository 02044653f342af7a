"""The BLAS libraries' own threads during a run (``blas_threads``, 1 unless told otherwise).

NumPy's and SciPy's matrix products call OpenBLAS, which splits a product bigger than a few
hundred thousand multiply-adds over a pool of its own threads, one per core. In a graph
that pool competes with everything else a run already spreads over the cores: the live
executor's component threads, and the threads components start themselves (R-SLAM's and FMT's
pools, scipy.fft's workers, OpenCV's). Over-subscribed, OpenBLAS's threads spin waiting for a
core: on the 2-core reference machine with one other job running, FMT's 9 x 256 x 128 peak window
product took 7 ms of CPU instead of 0.27 ms, and ``graphs/oxford.yaml`` on the RADIATE head ran in
93 s instead of 41 s (the same outputs, bit for bit). Dask's workers and joblib make the same
choice for the same reason. A run therefore limits every loaded BLAS library to ``blas_threads``
threads from its components' ``start()`` to their ``stop()``, and gives the libraries their
previous limits back after it; ``None`` (``--blas-threads 0``) leaves them alone, for a graph one
big product dominates and nothing else runs beside.

The limit is the process's (threadpoolctl sets it in the libraries themselves): a program that
runs a graph in one thread and its own matrix products in another gets one BLAS thread in both
while the graph runs. It is applied again once the components have started, for the libraries
their ``start()`` loaded (SciPy's own OpenBLAS, OpenCV's).
"""

from __future__ import annotations

from typing import Any

__all__ = ["NativeThreads", "check_blas_threads"]


def check_blas_threads(n: int | None) -> int | None:
    """``n`` if it is None or an int >= 1 (else ValueError naming it)."""
    if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 1):
        raise ValueError(f"blas_threads must be None (the libraries' own) or an integer >= 1, got {n!r}")
    return n


class NativeThreads:
    """Limits the loaded BLAS libraries to ``blas`` threads (:meth:`apply`, again for libraries loaded
    since) until :meth:`restore`; ``blas`` None: does nothing. ``blas`` as the executors checked it
    (:func:`check_blas_threads`)."""

    def __init__(self, blas: int | None) -> None:
        self.blas = blas
        self._limits: list[Any] = []

    def apply(self) -> None:
        if self.blas is None:
            return
        from threadpoolctl import threadpool_limits  # imported by a run, not by the engine's import

        self._limits.append(threadpool_limits(limits=self.blas, user_api="blas"))

    def restore(self) -> None:
        """The limits the libraries had before the first :meth:`apply` (the latest undone first)."""
        while self._limits:
            self._limits.pop().restore_original_limits()
