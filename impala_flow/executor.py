"""The deterministic discrete-event executor (offline: replay and simulation).

Events are processed on one thread in the order of the key
``(timestamp, graph order, sequence)``:

- ``timestamp``: the sample's time (int ns). A sample stamped earlier than the current
  time is delivered at once (its key is the smallest).
- ``graph order``: rank of the receiving component in the topological order of the
  graph (:meth:`Network.order`); a sample crossing a delayed connection is processed
  after every non-delayed event of the same timestamp.
- ``sequence``: a counter incremented for every event scheduled. Samples with equal
  timestamps at one input are therefore processed in emission order, and a source's
  samples with equal timestamps in the order it yielded them.

A sample reaches an input when its event is processed (never earlier: no input sees
the future), and a reactive input triggers its component then. When every source is
exhausted and every event processed, each component's ``flush(t)`` runs in graph order
(the events it causes processed before the next one's), then every ``stop()``. The same inputs give
the same order, hence bit-identical outputs, on any machine and at any replay speed:
the clock only sleeps between events.
"""

from __future__ import annotations

import heapq
import itertools
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

from .clock import ReplayClock
from .component import Component, Source
from .network import Network
from .ports import InputPort
from .sample import Sample
from .summary import ComponentError, RunSummary

__all__ = ["OfflineExecutor", "run_offline", "stop_components", "collect_counters"]

_SRC, _DELIVER, _TIMER = 0, 1, 2

ProgressFn = Callable[[int, int | None], None]


class OfflineExecutor:
    """Runs a :class:`Network` offline. ``stop_event`` ends it cleanly (Ctrl-C)."""

    def __init__(
        self, network: Network, clock: ReplayClock | None = None,
        progress: ProgressFn | None = None, stop_event: threading.Event | None = None,
        progress_interval_s: float = 0.25,
    ) -> None:
        self.net = network
        self.clock = clock or ReplayClock(None)
        self.progress = progress
        self.stop_event = stop_event or threading.Event()
        self.progress_interval_s = progress_interval_s
        self.summary = RunSummary(graph=network.name)

    # ------------------------------------------------------------------------------
    def run(self) -> RunSummary:
        order = self.net.order()
        n = len(order)
        rank = {c.name: i for i, c in enumerate(order)}
        heap: list[tuple] = []
        seq = itertools.count()
        push, pop = heapq.heappush, heapq.heappop
        summary = self.summary
        counts = {c.name: 0 for c in order}
        skipped = {c.name: 0 for c in order}
        skip = {name for name, pol in self.net.on_error.items() if pol == "skip"}
        live_events = 0  # events other than timers still scheduled

        def deliver(inp: InputPort, s: Sample, delayed: bool) -> None:
            nonlocal live_events
            push(heap, (s.timestamp, inp.rank + n if delayed else inp.rank, next(seq), _DELIVER, inp, s))
            live_events += 1

        for c in order:
            for out in c.outputs.values():
                out._deliver = deliver
            for inp in c.inputs.values():
                inp.rank = rank[c.name]

        # a source's clock offset (its clock vs the mission clock) is applied on the way in
        offsets = {c.name: int(getattr(c, "clock_offset_ns", 0) or 0) for c in order}
        started: list[Component] = []
        gens: dict[str, Iterator[tuple[int, str, Any]]] = {}
        last_src_t: dict[str, int] = {}
        wall0 = time.perf_counter()
        error: ComponentError | None = None
        cur_t: int | None = None

        def pull(src: Source) -> None:
            nonlocal live_events
            try:
                item = next(gens[src.name], None)
            except Exception as e:
                raise ComponentError(src.name, "generate", last_src_t.get(src.name), "generate", e) from e
            if item is None:
                return
            t, port, data = item
            if type(t) is not int:
                t = int(t)
            t += offsets[src.name]
            prev = last_src_t.get(src.name)
            if prev is not None and t < prev:
                raise ComponentError(src.name, port, t, "generate", ValueError(
                    f"source yielded t={t} ns after t={prev} ns: samples must come in time order"))
            last_src_t[src.name] = t
            push(heap, (t, rank[src.name], next(seq), _SRC, src, (port, data)))
            live_events += 1

        try:
            for c in order:
                if c.live:
                    raise ComponentError(c.name, "", None, "start", RuntimeError(
                        "is a live source: run this graph with the real-time executor (clock: {mode: realtime})"))
                try:
                    c.start()
                except Exception as e:
                    raise ComponentError(c.name, "", None, "start", e) from e
                started.append(c)
            for c in order:
                if isinstance(c, Source):
                    gens[c.name] = iter(c.generate())
                    pull(c)
            if heap:
                t0 = heap[0][0]
                for c in order:
                    for tname, timer in c.__timers__.items():
                        p = timer.period_ns(c)
                        first = -(-t0 // p) * p
                        push(heap, (first, rank[c.name], next(seq), _TIMER, c, (tname, p)))
            events = 0
            next_check = 256
            last_progress = wall0

            def drain() -> None:
                nonlocal cur_t, live_events, events, next_check, last_progress
                while heap:
                    t, _, _, kind, a, b = pop(heap)
                    if kind == _TIMER:
                        if live_events == 0:
                            return  # only timers left: the mission is over
                    else:
                        live_events -= 1
                    if cur_t is None or t > cur_t:
                        if cur_t is None:
                            summary.mission_start_ns = t
                        cur_t = t
                        self.clock.wait_until(t)
                    events += 1
                    if events >= next_check:
                        next_check = events + 256
                        if self.stop_event.is_set():
                            summary.interrupted = True
                            return
                        now = time.perf_counter()
                        if self.progress is not None and now - last_progress >= self.progress_interval_s:
                            last_progress = now
                            self.progress(cur_t, summary.mission_start_ns)
                    if kind == _DELIVER:
                        if not a.push(b):
                            continue
                        comp = a.owner
                        trig = a.trigger_name
                        t = b.timestamp
                    elif kind == _SRC:
                        port, data = b
                        try:
                            a.outputs[port].emit(t, data)
                        except KeyError:
                            raise ComponentError(a.name, port, t, "generate", KeyError(
                                f"yielded a sample for unknown output '{port}' "
                                f"(outputs: {', '.join(a.outputs) or 'none'})")) from None
                        pull(a)
                        continue
                    else:
                        comp = a
                        trig, p = b
                        push(heap, (t + p, rank[comp.name], next(seq), _TIMER, comp, b))
                    comp.trigger = trig
                    try:
                        comp.process(t)
                    except Exception as e:
                        if comp.name in skip:
                            skipped[comp.name] += 1
                            comp.log.warning("skipped t=%d ns after %s: %s", t, type(e).__name__, e)
                            continue
                        raise ComponentError(comp.name, trig, t, "process", e) from e
                    counts[comp.name] += 1

            drain()
            if not summary.interrupted:  # end of the inputs: components may emit what they hold
                for c in order:
                    if type(c).flush is Component.flush:
                        continue
                    c.trigger = "flush"
                    try:
                        c.flush(cur_t if cur_t is not None else 0)
                    except Exception as e:
                        raise ComponentError(c.name, "flush", cur_t, "flush", e) from e
                    drain()
            summary.events = events
        except ComponentError as e:
            error = e
        except KeyboardInterrupt:
            summary.interrupted = True
        finally:
            summary.mission_end_ns = cur_t
            stop_error = stop_components(started)
            error = error or stop_error
            summary.wall_s = time.perf_counter() - wall0
            summary.processed = counts
            summary.skipped = {k: v for k, v in skipped.items() if v}
            collect_counters(summary, order)
            if self.progress is not None and cur_t is not None:
                self.progress(cur_t, summary.mission_start_ns)
        if error is not None:
            summary.error = str(error)
            error.summary = summary  # type: ignore[attr-defined]
            raise error
        return summary


def collect_counters(summary: RunSummary, order: list[Component],
                     unconsumed: dict[InputPort, int] | None = None,
                     extra: dict[str, dict[str, Any]] | None = None) -> None:
    """Fill ``summary`` with every input's counters and every output's count at the end of a
    run (both executors): samples left in sync groups are ``unmatched``, samples left in a
    reactive FIFO ``unconsumed`` (plus those an executor already removed: ``unconsumed``);
    ``extra`` adds executor figures to the components' own ``summary()``."""
    for c in order:
        for g in c.sync_groups.values():
            for m in g.members:
                m.stats.unmatched += m.leftover() + (m._current is not None)
                m._fifo.clear()
                m._current = None
        for name, p in c.inputs.items():
            if p.group is None and p.policy == "reactive":
                p.stats.unconsumed = len(p._fifo) + (unconsumed or {}).get(p, 0)
            summary.inputs[f"{c.name}.{name}"] = vars(p.stats).copy()
        for name, o in c.outputs.items():
            summary.emitted[f"{c.name}.{name}"] = o.count
        figures = {**(c.summary() or {}), **(extra or {}).get(c.name, {})}
        if figures:
            summary.extra[c.name] = figures


def stop_components(started: list[Component]) -> ComponentError | None:
    """Call ``stop()`` of every started component, in order, even when some raise; return
    the first failure (naming its component) or None. Both executors end a run with it."""
    first: ComponentError | None = None
    for c in started:
        try:
            c.stop()
        except Exception as e:
            err = ComponentError(c.name, "", None, "stop", e)
            err.__cause__ = e
            first = first or err
    return first


def run_offline(network: Network, speed: float | None = None, **kw: Any) -> RunSummary:
    """Run ``network`` on the deterministic executor, paced at ``speed`` (None: max)."""
    return OfflineExecutor(network, ReplayClock(speed), **kw).run()
