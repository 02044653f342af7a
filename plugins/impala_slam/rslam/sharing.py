"""Work shared among R-SLAM's threads (``threads``) and the per-thread work arrays its
correlations write into. Every item of shared work is the same computation on its own data
whichever thread takes it, so the results do not depend on the scheduling."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from concurrent.futures import Executor, Future
from typing import Any

import numpy as np

__all__ = ["Shared", "resolved", "scratch", "shared_map"]


_SCRATCH = threading.local()
_SCRATCH_MAX_ARRAYS = 64  # per thread
_SCRATCH_MAX_BYTES = 512 << 20  # per thread; cleared past it (a new geometry), never grown without bound


def scratch(name: str, shape: tuple[int, ...], dtype: type = np.float32) -> np.ndarray:
    """A work array kept per thread and shape (contents undefined), overwritten by the next call
    with the same name and shape: a fresh multi-megabyte array costs its page faults at every
    turn (2-3 ms of the fine level's window DFT and energy on Beynes)."""
    pool = getattr(_SCRATCH, "pool", None)
    if pool is None:
        pool = _SCRATCH.pool = {}
    key = (name, shape, np.dtype(dtype).str)
    a = pool.get(key)
    if a is None:
        a = np.empty(shape, dtype)
        # shapes change only with the geometry: past the bounds, forget the old ones
        if len(pool) >= _SCRATCH_MAX_ARRAYS or sum(v.nbytes for v in pool.values()) + a.nbytes > _SCRATCH_MAX_BYTES:
            pool.clear()
        pool[key] = a
    return a


class Shared:
    """[fn(x) for x in items] computed by up to ``workers`` threads of ``pool``, which start at
    once, and by the calling thread from :meth:`join` on: each takes the next item until none is
    left. Every item is the same computation on its own data whichever thread takes it, so the
    results are bit-identical to ``pool=None`` (all on the calling thread)."""

    def __init__(self, pool: Executor | None, workers: int, fn: Callable, items: list) -> None:
        self.fn, self.items = fn, items
        self.out: list = [None] * len(items)
        self._order = iter(range(len(items)))
        self._lock = threading.Lock()
        n = min(workers, len(items)) if pool is not None else 0
        self._futures = [pool.submit(self._work) for _ in range(n)] if pool is not None else []

    def _work(self) -> float:
        c0 = time.thread_time()
        while True:
            with self._lock:
                i = next(self._order, None)
            if i is None:
                return time.thread_time() - c0
            self.out[i] = self.fn(self.items[i])

    def join(self) -> tuple[list, float]:
        """(the results in the items' order, the thread CPU seconds the pool's threads spent)."""
        self._work()
        return self.out, sum(f.result() for f in self._futures)


def shared_map(pool: Executor | None, workers: int, fn: Callable, items: list) -> tuple[list, float]:
    """[fn(x) for x in items] shared among the calling thread and up to ``workers`` threads of
    ``pool`` (:class:`Shared`, the calling thread taking its share at once), with the thread
    CPU seconds the pool's threads spent; bit-identical to ``pool=None`` when each item is
    computed on its own data."""
    return Shared(pool, min(workers, len(items) - 1), fn, items).join()


def resolved(value: Any) -> Any:
    """``value``, or its result when it is a future (waited for)."""
    return value.result() if isinstance(value, Future) else value
