"""Durations of a run, per component: time per ``process`` call and latency per output.

A :class:`Histogram` counts int ns durations in log-linear buckets (exact below 128 ns, then
64 buckets per power of two: every value is kept within 1.6 % of itself), so it answers the
median and the p99 of a whole run in bounded memory (at most 64 x 64 buckets, a few hundred
in practice) for a few hundred ns per value (appended to a bounded buffer, folded with numpy),
whatever the run's length.

What the executors record (:mod:`impala_flow._offline`, :mod:`impala_flow._realtime`):

- **time per call** (both executors): ``time.perf_counter_ns()`` around every ``process``
  call of a component (the calls that raised included): ``summary.timing[component]`` with
  ``calls``, ``median_ms``, ``p99_ms``, ``max_ms``, ``total_s`` and ``share`` (of the run's
  wall time; in real time components run in parallel, so shares can add up past 1).
- **latency** (the real-time executor only): a sample entering the graph from a source
  carries its *origin*, the mission clock when it arrived; a sample a component emits
  inherits the origin of the sample that triggered the ``process`` call emitting it (a sync
  group: its latest member's; a timer: the tick's time; a component that held the work
  for later, what it set back with ``Component.work_origin_ns``). Per component output,
  ``summary.latency["component.output"]`` holds the distribution of ``mission clock at emit -
  origin``: from the arrival of the sample that completed the work to its result (for a
  radar chain, from the beam that completes a turn to that turn's pose). Offline, mission
  time does not advance while a component computes: there is no latency to report, and
  nothing is recorded (the outputs are bit-identical with or without the figures).
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["Histogram", "timing_figures", "latency_figures"]

_SUB_BITS = 6     # 64 buckets per power of two
_EXACT = 1 << (_SUB_BITS + 1)


class Histogram:
    """Counts of non-negative int durations (ns) in log-linear buckets (see the module docstring).

    :meth:`add` only appends to a buffer of at most ``fold_every`` values (a few hundred ns a
    value in an executor's loop); the buffer is folded into the buckets with numpy when full
    and before any figure is read."""

    __slots__ = ("counts", "_n", "_total", "_max", "buf", "fold_every")

    def __init__(self, fold_every: int = 4096) -> None:
        self.counts: dict[int, int] = {}
        self._n = 0
        self._total = 0
        self._max = 0
        self.buf: list[int] = []
        self.fold_every = fold_every

    def add(self, v: int) -> None:
        """Count one duration ``v`` ns (a negative one counts as 0)."""
        buf = self.buf
        buf.append(v)
        if len(buf) >= self.fold_every:
            self.fold()

    def fold(self) -> None:
        """Move the buffered values into the buckets."""
        if not self.buf:
            return
        v = np.maximum(np.array(self.buf, dtype=np.int64), 0)
        self.buf.clear()
        e = np.frexp(v.astype(np.float64))[1].astype(np.int64)    # bit length (exact below 2**53 ns)
        shift = np.maximum(e - _SUB_BITS - 1, 0)
        idx = np.where(v < _EXACT, v, (e << _SUB_BITS) | ((v >> shift) & ((1 << _SUB_BITS) - 1)))
        keys, n = np.unique(idx, return_counts=True)
        counts = self.counts
        for k, c in zip(keys.tolist(), n.tolist(), strict=True):
            counts[k] = counts.get(k, 0) + c
        self._n += int(v.size)
        self._total += int(v.sum())
        self._max = max(self._max, int(v.max()))

    @property
    def n(self) -> int:
        """Durations counted."""
        self.fold()
        return self._n

    @property
    def total(self) -> int:
        """Their sum, ns."""
        self.fold()
        return self._total

    @property
    def max(self) -> int:
        """The longest, ns (exact)."""
        self.fold()
        return self._max

    @staticmethod
    def _value(idx: int) -> float:
        """The middle of bucket ``idx``."""
        if idx < _EXACT:
            return float(idx)
        e, m = idx >> _SUB_BITS, idx & ((1 << _SUB_BITS) - 1)
        lo = ((1 << _SUB_BITS) | m) << (e - _SUB_BITS - 1)
        return lo + (1 << (e - _SUB_BITS - 1)) / 2

    def quantile(self, q: float) -> float:
        """The ``q`` quantile (0..1) in ns: the middle of the bucket holding it (0 when empty)."""
        if not self.n:
            return 0.0
        rank = q * (self._n - 1)
        seen = 0
        for idx in sorted(self.counts):
            seen += self.counts[idx]
            if seen > rank:
                return min(self._value(idx), float(self._max))
        return float(self._max)


def timing_figures(hists: dict[str, Histogram], wall_s: float) -> dict[str, dict[str, Any]]:
    """``summary.timing``: per component with calls, its time per ``process`` call."""
    out = {}
    for name, h in hists.items():
        if h.n:
            out[name] = {"calls": h.n, "median_ms": round(h.quantile(0.5) / 1e6, 4),
                         "p99_ms": round(h.quantile(0.99) / 1e6, 4), "max_ms": round(h.max / 1e6, 4),
                         "total_s": round(h.total / 1e9, 6),
                         "share": round(h.total / 1e9 / wall_s, 4) if wall_s > 0 else 0.0}
    return out


def latency_figures(hists: dict[str, Histogram]) -> dict[str, dict[str, Any]]:
    """``summary.latency``: per component output with samples, emit minus origin on the mission clock."""
    return {key: {"count": h.n, "median_ms": round(h.quantile(0.5) / 1e6, 3),
                  "p99_ms": round(h.quantile(0.99) / 1e6, 3), "max_ms": round(h.max / 1e6, 3)}
            for key, h in hists.items() if h.n}
