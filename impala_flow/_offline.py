"""The deterministic discrete-event executor (offline: replay and simulation).

Events are processed on one thread in the order of the key
``(timestamp, graph rank, phase, sequence)``:

- ``timestamp``: the sample's time (int ns). A sample stamped earlier than the current
  time is delivered at once (its key is the smallest).
- ``graph rank``: the receiving component's position in the topological order of the
  graph over its non-delayed connections, ties broken by component id (never by the
  order of the YAML file); a sample crossing a delayed connection is processed after
  every non-delayed event of the same timestamp.
- ``phase``: at one timestamp, a component receives (its inputs are pushed) before it
  fires (``process`` runs for reactive inputs, completed sync groups and timers).
- ``sequence``: a counter incremented for every event scheduled. Samples with equal
  timestamps at one input are therefore processed in emission order, and a source's
  samples with equal timestamps in the order it yielded them.

The equal-timestamp rule
    a component fires for time ``t`` only after every sample stamped ``<= t`` that can
    still reach it through non-delayed connections has arrived at its inputs, whatever
    the length of the paths and the order of the YAML file. A trigger stamped ``t`` thus
    sees, in a ``history`` or ``sampling`` input, a sample stamped ``t`` that travelled
    through any number of pass-through hops. (It holds because every producer of a
    component ranks before it, and events run in key order.) Samples a component emits
    stamped earlier than its own trigger arrive late, as they are produced; samples
    crossing a delayed connection arrive after the non-delayed ones of their time.

The trigger runs at once when nothing else can reach the component at that time (the
common case costs one event per hop); otherwise it is queued behind the other arrivals.
A sample reaches an input when its event is processed (never earlier: no input sees the
future). When every source is exhausted and every event processed, each component's
``flush(t)`` runs in graph order (the events it causes processed before the next one's),
then every ``stop()``. The same inputs give the same order, hence bit-identical outputs,
on any machine and at any replay speed: the clock only sleeps between events.

Periodic timers fire at every multiple of their period while the mission runs, with two
bounds so that no period and no mission can keep the executor spinning:

- before anything starts, a timer that would fire more than :data:`MAX_TIMER_FIRINGS` times
  over the mission's span (the longest duration its sources announce) is refused, naming
  the component, the parameter and the count (:func:`timer_problems`);
- over a gap where nothing at all is pending, a timer whose component has received no
  sample for :data:`IDLE_TIMER_FIRINGS` firings in a row skips ahead: its next firing is the
  first multiple of its period at or after the next pending event. The skipped firings are
  counted (``timer_firings_skipped`` in the component's summary figures). The rule reads
  only the event queue, so it is deterministic; a run whose timers never idle that long
  is unchanged by it.

Failures (the lifecycle both executors share, :mod:`impala_flow._lifecycle`; this module keeps
only the event loop): the first error is raised, with the summary attached (``error.summary``, the
events processed so far included); ``stop()`` runs for every component whose ``start()``
was called, even one whose ``start()`` raised (so it can release what it took);
``summary()`` only for those whose ``start()`` returned. A ``stop()`` or ``summary()`` that
raises is reported on its own line (``RunSummary.errors``), never instead of the first.
Samples still in flight when a run is interrupted or fails are counted as ``unconsumed``
(``unmatched`` in sync groups) at the inputs they were going to.

``duration_ns`` (``--duration``) stops reading the sources at the mission's first time + that
span, then ends as at the end of the inputs (flush included): the run of the shortened inputs.
Every ``process`` call is timed with ``time.perf_counter_ns`` into ``summary.timing``
(:mod:`impala_flow._timing`); the timing never feeds back into the run, so outputs stay
bit-identical. No latency is reported offline (mission time stands still while a component runs).
"""

from __future__ import annotations

import heapq
import itertools
import threading
import time
from collections.abc import Callable
from typing import Any

from ._clock import ReplayClock
from ._component import Component, Source
from ._lifecycle import Lifecycle, check_source_time
from ._native import check_blas_threads
from ._network import Network
from ._ports import InputPort, OutputPort, OutputTypeError
from ._summary import ComponentError, RunSummary, log_skip
from ._timing import Histogram, timing_figures

__all__ = ["OfflineExecutor", "run_offline", "timer_problems", "MAX_TIMER_FIRINGS", "IDLE_TIMER_FIRINGS"]

_SRC, _DELIVER, _TIMER, _TRIG = 0, 1, 2, 3
_BEFORE_ALL = -(1 << 63) - 1  # earlier than any int64 sample time
_INT64_MIN, _INT64_MAX = -(1 << 63), (1 << 63) - 1  # as impala_flow._lifecycle's, module globals of the hot loop

ProgressFn = Callable[[int, int | None], None]

#: most firings of one periodic timer over a mission's span (10 Hz for 11 days)
MAX_TIMER_FIRINGS = 10_000_000
#: firings in a row without a new sample after which an idle timer skips an empty gap
IDLE_TIMER_FIRINGS = 1000


def _years(span_s: float) -> str:
    return f" ({span_s / 31_557_600:.1f} years)" if span_s >= 31_557_600 else ""


def timer_problems(network: Network) -> list[str]:
    """One line per periodic timer that would fire more than :data:`MAX_TIMER_FIRINGS`
    times over the mission's span (see :func:`_timer_spins`)."""
    return [f"component '{name}' ({kind}): {why}" for name, kind, why in _timer_spins(network)]


def _timer_spins(network: Network) -> list[tuple[str, str, str]]:
    """(component, type, why) per periodic timer that would fire more than :data:`MAX_TIMER_FIRINGS`
    times over the mission's span (the longest ``duration_hint_ns()`` of the sources; no
    check when none knows it). A period of 1e-9 s on a minute of mission, or a mission whose
    times span decades, is refused here, before anything starts."""
    hints = []
    for c in network.components.values():
        if isinstance(c, Source):
            try:
                h = c.duration_hint_ns()
            except Exception:  # noqa: BLE001 - only a hint
                h = None
            if h:
                hints.append(int(h))
    if not hints:
        return []
    span = max(hints)
    out = []
    for c in network.components.values():
        for tname, timer in c.__timers__.items():
            p = timer.period_ns(c)
            firings = span // p + 1
            if firings > MAX_TIMER_FIRINGS:
                param = f"parameter '{timer.period}' = {timer.period_s(c._params):g} s" \
                    if isinstance(timer.period, str) else f"period {timer.period_s(c._params):g} s"
                kind = type(c).type_name or type(c).__name__
                out.append((c.name, kind, f"{param}: timer '{tname}' would fire {firings:.3g} times "
                           f"over the mission's {span / 1e9:.6g} s{_years(span / 1e9)}, more than "
                           f"{MAX_TIMER_FIRINGS:.0e}: raise the period, or check the mission's times"))
    return out


def _wire(order: list[Component], heap: list[tuple],
          next_seq: Callable[[], int]) -> tuple[list[OutputPort], list[InputPort]]:
    """Point every output at the event heap and rank every input; return (outputs, inputs).

    An event's second key is ``2 * rank + phase`` (0: an input receives, 1: a component
    fires); a delayed connection adds ``2 * len(order)``. ``emit()`` queues
    ``(t, key, seq, _DELIVER, input, sample)`` itself (:class:`~impala_flow._ports.OutputPort`);
    a lone reactive input without history takes the inlined fast path (``_fast``)."""
    for i, c in enumerate(order):
        for inp in c.inputs.values():
            inp.rank = 2 * i
    delayed_shift = 2 * len(order)
    outputs = [out for c in order for out in c.outputs.values()]
    for out in outputs:
        out._heap, out._next = heap, next_seq
        out._keyed = tuple((inp, inp.rank + delayed_shift if delayed else inp.rank) for inp, delayed in out._targets)
    inputs = [inp for c in order for inp in c.inputs.values()]
    for inp in inputs:
        inp._fast = inp.group is None and inp.policy == "reactive" and inp._history_ns is None and inp._cond is None
    return outputs, inputs


def _unwire(heap: list[tuple], outputs: list[OutputPort], inputs: list[InputPort]) -> dict[InputPort, int]:
    """Empty the heap and detach the ports (they may outlive this run, and be run again);
    return the samples emitted but never delivered (interrupt, error), per input: lost, counted."""
    in_flight: dict[InputPort, int] = {}
    for ev in heap:
        if ev[3] == _DELIVER:
            in_flight[ev[4]] = in_flight.get(ev[4], 0) + 1
    heap.clear()
    for out in outputs:
        out._heap, out._next, out._keyed = None, None, ()
    for inp in inputs:
        inp._fast = False
    return in_flight


def _live_source(c: Component) -> str | None:
    if c.live:
        return "is a live source: run this graph with the real-time executor (clock: {mode: realtime})"
    return None


class OfflineExecutor:
    """Runs a :class:`Network` offline. ``stop_event`` ends it cleanly (Ctrl-C).

    ``duration_ns`` ends the run after that much mission time: a source's samples stamped at
    or after the mission's first time + ``duration_ns`` are not taken (its generator is
    closed), what was taken is processed and every component flushed, as at the end of the
    inputs; the summary says so (``stopped_at_duration``). The run is the same as one whose
    sources ended there, hence as deterministic. ``blas_threads``: the BLAS libraries' own
    threads while the components run (:mod:`impala_flow._native`; None: the libraries' own).
    """

    def __init__(
        self, network: Network, clock: ReplayClock | None = None,
        progress: ProgressFn | None = None, stop_event: threading.Event | None = None,
        progress_interval_s: float = 0.25, duration_ns: int | None = None, blas_threads: int | None = 1,
    ) -> None:
        if duration_ns is not None and duration_ns <= 0:
            raise ValueError(f"duration_ns must be > 0, got {duration_ns}")
        self.duration_ns = duration_ns
        self.blas_threads = check_blas_threads(blas_threads)
        self.net = network
        self.clock = clock or ReplayClock(None)
        self.progress = progress
        self.stop_event = stop_event or threading.Event()
        self.progress_interval_s = progress_interval_s
        self.summary = RunSummary(graph=network.name)

    # ------------------------------------------------------------------------------
    def run(self) -> RunSummary:  # noqa: C901 - the event loop stays in one frame for speed
        # start, stop, errors, counters, the BLAS limit: shared with the real-time executor
        life = Lifecycle(self.net, self.summary, self.blas_threads)
        order = life.order
        rank = {c.name: i for i, c in enumerate(order)}
        heap: list[tuple] = []
        seq = itertools.count()
        push, pop = heapq.heappush, heapq.heappop
        summary = self.summary
        counts = {c: 0 for c in order}  # by component: no .name lookup per call
        for c in order:
            c._origin_tl = None  # no latency offline: work_origin_ns is None (a live run may have set it)
        hists = {c: Histogram() for c in order}  # time per process call (perf_counter_ns)
        pc = time.perf_counter_ns
        duration_ns = self.duration_ns
        end_ns = _INT64_MAX + 1  # the first source time not taken (--duration), known at the first event
        summary.duration_s = None if duration_ns is None else duration_ns / 1e9
        skipped = {c.name: 0 for c in order}
        timers_skipped: dict[Component, int] = {}
        skip = {name for name, pol in self.net.on_error.items() if pol == "skip"}
        next_seq = seq.__next__
        outputs, inputs = _wire(order, heap, next_seq)
        # every timer has exactly one event in the heap (re-queued when it fires): the events
        # other than timers are len(heap) - timers, and when a timer is popped the others
        # are len(heap) - (timers - 1)
        n_timers = sum(len(c.__timers__) for c in order)

        # a source's clock offset (its clock vs the mission clock) is applied on the way in
        offsets = {c.name: int(getattr(c, "clock_offset_ns", 0) or 0) for c in order}
        wall0 = life.wall0
        error: ComponentError | None = None
        cur_t: int | None = None  # the time of the last event (None before the first)
        now_t = _BEFORE_ALL  # the same, as an int for the hot loop
        events = 0

        # per source: [generator, clock offset, event key, last time yielded]
        src_state: dict[Source, list] = {}

        def pull(src: Source) -> None:
            st = src_state[src]
            try:
                item = next(st[0], None)
            except Exception as e:
                raise ComponentError(src.name, "generate", st[3], "generate", e) from e
            if item is None:
                return
            t, port, data = item
            if type(t) is not int:
                t = int(t)
            t += st[1]
            if not _INT64_MIN <= t <= _INT64_MAX:
                check_source_time(src.name, port, t)
            prev = st[3]
            if prev is not None and t < prev:
                raise ComponentError(src.name, port, t, "generate", ValueError(
                    f"source yielded t={t} ns after t={prev} ns: samples must come in time order"))
            st[3] = t
            push(heap, (t, st[2], next_seq(), _SRC, src, (port, data)))

        def close_source(src: Source, t: int) -> None:
            """--duration reached: close ``src``'s generator (its cleanup runs), take nothing more."""
            summary.stopped_at_duration = True
            close = getattr(src_state[src][0], "close", None)
            if close is not None:
                try:
                    close()
                except Exception as e:
                    raise ComponentError(src.name, "generate", t, "generate", e) from e

        def failed(comp: Component, trig: str, t: int, e: Exception) -> None:
            """A ``process`` call raised: count and log it (``on_error: skip``) or stop the run."""
            if comp.name not in skip:
                raise ComponentError(comp.name, trig, t, "process", e) from e
            skipped[comp.name] += 1
            if skipped[comp.name] == 1:
                summary.first_skip[comp.name] = f"t={t} ns: {type(e).__name__}: {e}"
            log_skip(comp.log, skipped[comp.name], t, e)

        try:
            spins = _timer_spins(self.net)  # before any start(): nothing to undo
            if spins:
                raise ComponentError(spins[0][0], "", None, "start", ValueError(spins[0][2]))
            life.start(refuse=_live_source)
            for c in order:
                if isinstance(c, Source):
                    src_state[c] = [iter(c.generate()), offsets[c.name], 2 * rank[c.name] + 1, None]
                    pull(c)
            if heap:
                t0 = heap[0][0]
                for c in order:
                    for tname, timer in c.__timers__.items():
                        p = timer.period_ns(c)
                        first = -(-t0 // p) * p
                        # [name, period, samples received at the last firing, idle firings in a row]
                        push(heap, (first, 2 * rank[c.name] + 1, next(seq), _TIMER, c, [tname, p, -1, 0]))
            next_check = 256
            last_progress = wall0
            clock = self.clock  # an unpaced replay clock never waits: no call per timestamp
            wait_until = None if type(clock) is ReplayClock and clock.speed is None else clock.wait_until

            def drain() -> None:
                nonlocal cur_t, now_t, events, next_check, last_progress, end_ns
                while heap:
                    ev = pop(heap)
                    t, k, _, kind, a, b = ev
                    if kind == _SRC and t >= end_ns:  # past --duration: this source is not read further
                        close_source(a, t)
                        continue
                    if t > now_t:
                        if kind == _TIMER and len(heap) == n_timers - 1:
                            push(heap, (t, k, next_seq(), kind, a, b))  # kept for a flush that emits
                            return  # only timers left, past the last sample: the mission is over
                        if cur_t is None:
                            summary.mission_start_ns = t
                            if duration_ns is not None:
                                end_ns = t + duration_ns
                        cur_t = now_t = t
                        if wait_until is not None:
                            wait_until(t)
                    if kind != _TRIG:
                        events += 1
                        if events >= next_check:
                            next_check = events + 256
                            if self.stop_event.is_set():
                                summary.interrupted = True
                                push(heap, ev)  # not processed: still in flight, counted as such
                                return
                            now = time.perf_counter()
                            if self.progress is not None and now - last_progress >= self.progress_interval_s:
                                last_progress = now
                                self.progress(cur_t, summary.mission_start_ns)
                    if kind == _DELIVER:
                        fifo = a._fifo
                        if a._fast and not fifo:  # InputPort.push, inlined: a lone sample always fits
                            if a.validate and a.invalid(b):
                                continue  # dropped and counted as invalid
                            st = a.stats
                            st.received += 1
                            a._last = b
                            fifo.append(b)
                            if st.high_water < 1:
                                st.high_water = 1
                        elif not a.push(b):
                            continue
                        if heap and heap[0][0] == t and heap[0][1] <= k + 1:
                            # more arrivals for this component at this time, or triggers already
                            # waiting: fire after them, in arrival order (the equal-timestamp rule)
                            push(heap, (t, k + 1, next_seq(), _TRIG, a, None))
                            continue
                    elif kind == _TRIG:  # a deferred trigger of input a
                        if a.group is None and a.policy == "reactive" and not a._fifo:
                            continue  # its sample was dropped (drop_oldest) or taken already
                    elif kind == _SRC:
                        port, data = b
                        out = a.outputs.get(port)
                        if out is None:
                            raise ComponentError(a.name, port, t, "generate", KeyError(
                                f"yielded a sample for unknown output '{port}' "
                                f"(outputs: {', '.join(a.outputs) or 'none'})"))
                        try:
                            out.emit(t, data)
                        except OutputTypeError as e:
                            raise ComponentError(a.name, port, t, "generate", e) from e
                        pull(a)
                        continue
                    else:  # a periodic timer of component a
                        trig, p = b[0], b[1]
                        got = sum(inp.stats.received for inp in a.inputs.values())
                        b[3] = b[3] + 1 if got == b[2] else 0
                        b[2] = got
                        due = t + p
                        # idle for long and nothing else due before its next firing: it may skip a gap
                        idle = b[3] >= IDLE_TIMER_FIRINGS and not (heap and heap[0][0] <= due and heap[0][3] != _TIMER)
                        if not idle:
                            push(heap, (due, k, next(seq), _TIMER, a, b))
                        a.trigger = trig
                        t0 = pc()
                        try:
                            a.process(t)
                        except Exception as e:
                            failed(a, trig, t, e)
                        else:
                            counts[a] += 1
                        hists[a].add(pc() - t0)
                        if idle:  # after process(): what it emitted counts as pending
                            pending = [e[0] for e in heap if e[3] != _TIMER]
                            if pending and min(pending) > due:  # skip to the next pending event
                                nxt = -(-min(pending) // p) * p
                                timers_skipped[a] = timers_skipped.get(a, 0) + (nxt - due) // p
                                due = nxt
                            push(heap, (due, k, next(seq), _TIMER, a, b))
                        continue
                    # input a fires its component (a reactive input, or a completed sync group)
                    comp = a.owner
                    group = a.group
                    if group is None:
                        trig = a.trigger_name
                    else:
                        cur = [m._current for m in group.members]
                        if None in cur:
                            continue
                        trig = group.name
                        t = max(x.timestamp for x in cur)  # type: ignore[union-attr]
                    comp.trigger = trig
                    t0 = pc()
                    try:
                        comp.process(t)
                    except Exception as e:
                        failed(comp, trig, t, e)
                    else:
                        counts[comp] += 1
                    hists[comp].add(pc() - t0)
                    if group is not None and group.match():  # samples that arrived while it was pending
                        push(heap, (ev[0], k | 1, next(seq), _TRIG, a, None))

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
        except ComponentError as e:
            error = e
        except KeyboardInterrupt:
            summary.interrupted = True
        finally:
            summary.events = events
            summary.mission_end_ns = cur_t
            in_flight = _unwire(heap, outputs, inputs)
            error = life.finish(error, processed={c.name: n for c, n in counts.items()},
                                skipped={k: v for k, v in skipped.items() if v}, unconsumed=in_flight,
                                extra={c.name: {"timer_firings_skipped": n} for c, n in timers_skipped.items()})
            summary.timing = timing_figures({c.name: h for c, h in hists.items()}, summary.wall_s)
            if self.progress is not None and cur_t is not None:
                self.progress(cur_t, summary.mission_start_ns)
        return life.result(error)


def run_offline(network: Network, speed: float | None = None, **kw: Any) -> RunSummary:
    """Run ``network`` on the deterministic executor, paced at ``speed`` (None: max); keywords as
    :class:`OfflineExecutor` (``duration_ns``, ``stop_event``, ...)."""
    return OfflineExecutor(network, ReplayClock(speed), **kw).run()
