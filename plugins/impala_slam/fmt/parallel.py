"""Threads for the independent correlations of one FMT registration.

A registration tries rotations whose translations do not depend on each other: the two
candidates theta and theta + pi, then each step of the refinement's theta - step and
theta + step. :class:`TaskPool` computes such a batch on a few threads and returns the
results in the batch's order, so what :func:`impala_slam.fmt.core.register` decides from
them (and every figure it returns) is the same bits with 1 thread or 2: each task is the same
deterministic computation whichever thread runs it. The work is NumPy, OpenCV and
scipy.fft on arrays of 10^5 cells, all releasing the GIL.

It also counts the CPU time its worker threads spend (``cpu_s``), so that a caller timing its
own thread (``time.thread_time``) can add what it handed off.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any

__all__ = ["TaskPool"]


class TaskPool:
    """``threads`` threads (the caller's included) for batches of independent tasks."""

    def __init__(self, threads: int, name: str = "fmt"):
        if threads < 1:
            raise ValueError(f"threads must be at least 1, got {threads}")
        self.threads = threads
        # the caller runs the batch's first task itself: threads - 1 workers
        self._pool = ThreadPoolExecutor(threads - 1, thread_name_prefix=name) if threads > 1 else None
        self._lock = threading.Lock()
        self.cpu_s = 0.0  # CPU time of the worker threads' tasks

    def _timed(self, fn: Callable[..., Any], args: tuple) -> Any:
        c0 = time.thread_time()
        try:
            return fn(*args)
        finally:
            dt = time.thread_time() - c0
            with self._lock:
                self.cpu_s += dt

    def map(self, fn: Callable[..., Any], batch: Sequence[tuple]) -> list[Any]:
        """``[fn(*args) for args in batch]``, the tasks shared between the threads."""
        if self._pool is None or len(batch) < 2:
            return [fn(*args) for args in batch]
        futures = [self._pool.submit(self._timed, fn, args) for args in batch[1:]]
        first = fn(*batch[0])
        return [first] + [f.result() for f in futures]

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
