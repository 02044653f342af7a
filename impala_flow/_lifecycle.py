"""The run lifecycle both executors share: start, stop, errors, counters, summary.

An executor (:mod:`impala_flow._offline`, :mod:`impala_flow._realtime`) keeps only its
scheduling loop; around it, :class:`Lifecycle`

- limits the BLAS libraries' own threads from the components' start to their stop
  (:class:`~impala_flow._native.NativeThreads`, ``blas_threads``: 1 by default);
- orders the components (:func:`event_order`: topological over the non-delayed connections,
  ties by component id, never by the YAML file's order) and starts them in that order
  (:meth:`Lifecycle.start`); a component whose ``start()`` raises is still stopped (it may
  release what it took) but not asked for its ``summary()``;
- at the end (:meth:`Lifecycle.finish`), whatever happened, stops every started component in
  order even when some raise (:func:`stop_components`), fills the summary (wall time,
  ``process`` calls, skips, every input's counters and every output's count:
  :func:`collect_counters`) and picks the error to raise: the first one, the later ones on
  their own lines (``RunSummary.errors``), never instead of the first;
- :meth:`Lifecycle.result` raises that error with the summary attached (``error.summary``)
  or returns the summary.

Sources are checked the same way by both (:func:`check_source_time`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from ._component import Component
from ._native import NativeThreads
from ._network import Network, topological_order
from ._ports import InputPort
from ._summary import ComponentError, RunSummary

__all__ = ["Lifecycle", "event_order", "check_source_time", "stop_components", "collect_counters",
           "INT64_MIN", "INT64_MAX"]

INT64_MIN, INT64_MAX = -(1 << 63), (1 << 63) - 1


def event_order(network: Network) -> list[Component]:
    """Topological order over the non-delayed connections, ties broken by component id:
    the same graph gives the same order whatever the order of its YAML file
    (``CycleError`` from :meth:`Network.order` for a cycle without a delay)."""
    network.order()  # raises CycleError, naming the cycle
    names = topological_order(network.components, network.edges(include_delayed=False), str)
    assert names is not None  # no cycle: order() said so
    return [network.components[n] for n in names]


def check_source_time(name: str, port: str, t: int) -> None:
    """Refuse a timestamp outside int64 (MCAP ``log_time``, numpy ``int64``) at its source."""
    if not INT64_MIN <= t <= INT64_MAX:
        raise ComponentError(name, port, None, "generate", OverflowError(
            f"yielded t={t} ns on '{port}', outside the int64 range of timestamps "
            f"[{INT64_MIN}, {INT64_MAX}] ns"))


class Lifecycle:
    """One run's start, stop, error and counter bookkeeping (see the module docstring)."""

    def __init__(self, network: Network, summary: RunSummary, blas_threads: int | None = 1) -> None:
        self.summary = summary
        self.order = event_order(network)  # raises CycleError, naming the cycle
        self.native = NativeThreads(blas_threads)
        summary.blas_threads = blas_threads
        self.started: list[Component] = []
        self.start_failed: set[str] = set()
        self.wall0 = time.perf_counter()

    def start(self, refuse: Callable[[Component], str | None] | None = None) -> None:
        """``start()`` every component in order; ``refuse(c)`` (a reason, or None) is asked
        first and stops the run before ``c`` starts. Raises the first failure as a
        :class:`ComponentError` (phase ``start``). The BLAS limit is set before the first and
        again after the last (for the libraries their ``start()`` loaded)."""
        self.native.apply()
        for c in self.order:
            why = refuse(c) if refuse is not None else None
            if why:
                raise ComponentError(c.name, "", None, "start", RuntimeError(why))
            self.started.append(c)  # stop() runs even if start() raises: it may release what start() took
            try:
                c.start()
            except Exception as e:
                self.start_failed.add(c.name)
                raise ComponentError(c.name, "", None, "start", e) from e
        self.native.apply()

    def finish(self, error: ComponentError | None, processed: dict[str, int], skipped: dict[str, int],
               unconsumed: dict[InputPort, int] | None = None, extra: dict[str, dict[str, Any]] | None = None,
               earlier: list[ComponentError] | None = None) -> ComponentError | None:
        """Stop the started components and fill the summary; return the error to raise:
        ``error``, else the first of ``earlier`` (failures the executor collected after its
        first) and of the stop/summary failures; the others go to ``summary.errors``."""
        try:
            later = list(earlier or []) + stop_components(self.started)
        finally:
            self.native.restore()
        summary = self.summary
        summary.wall_s = time.perf_counter() - self.wall0
        summary.processed = processed
        summary.skipped = skipped
        later += collect_counters(summary, self.order, unconsumed, extra,
                                  reporting=[c for c in self.started if c.name not in self.start_failed])
        if error is None and later:
            error, later = later[0], later[1:]
        summary.errors += [str(e) for e in later]
        return error

    def result(self, error: ComponentError | None) -> RunSummary:
        """The summary, or ``error`` raised with the summary attached."""
        summary = self.summary
        if error is not None:
            summary.error = str(error)
            error.summary = summary  # type: ignore[attr-defined]
            raise error
        return summary


def collect_counters(summary: RunSummary, order: list[Component],
                     unconsumed: dict[InputPort, int] | None = None,
                     extra: dict[str, dict[str, Any]] | None = None,
                     reporting: list[Component] | None = None) -> list[ComponentError]:
    """Fill ``summary`` with every input's counters and every output's count at the end of a
    run (both executors): samples left in sync groups are ``unmatched``, samples left in a
    reactive FIFO ``unconsumed``, plus those an executor already removed or never delivered
    (``unconsumed``: counted as ``unmatched`` for sync-group members, ``unconsumed``
    otherwise); ``extra`` adds executor figures to the components' own ``summary()``.

    ``summary()`` is asked of the ``reporting`` components only (default: all; the
    executors pass those whose ``start()`` returned). One that raises is returned as a
    :class:`ComponentError` (phase ``summary``), never raised: the caller reports it."""
    lost = unconsumed or {}
    failures: list[ComponentError] = []
    asked = None if reporting is None else {c.name for c in reporting}
    for c in order:
        for g in c.sync_groups.values():
            for m in g.members:
                m.stats.unmatched += m.leftover() + (m._current is not None) + lost.get(m, 0)
                m._fifo.clear()
                m._current = None
        for name, p in c.inputs.items():
            if p.group is None:
                if p.policy == "reactive":
                    p.stats.unconsumed = len(p._fifo) + lost.get(p, 0)
                else:
                    p.stats.unconsumed += lost.get(p, 0)
            summary.inputs[f"{c.name}.{name}"] = vars(p.stats).copy()
        for name, o in c.outputs.items():
            summary.emitted[f"{c.name}.{name}"] = o.count
        own: dict[str, Any] = {}
        if asked is None or c.name in asked:
            try:
                own = dict(c.summary() or {})
            except Exception as e:
                err = ComponentError(c.name, "", None, "summary", e)
                err.__cause__ = e
                failures.append(err)
        figures = {**own, **(extra or {}).get(c.name, {})}
        if figures:
            summary.extra[c.name] = figures
    return failures


def stop_components(started: list[Component]) -> list[ComponentError]:
    """Call ``stop()`` of every started component, in order, even when some raise; return
    every failure (each naming its component), in order. Both executors end a run with it."""
    failures: list[ComponentError] = []
    for c in started:
        try:
            c.stop()
        except Exception as e:
            err = ComponentError(c.name, "", None, "stop", e)
            err.__cause__ = e
            failures.append(err)
    return failures
