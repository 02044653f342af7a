"""The real-time threaded executor (live sources, ``clock: {mode: realtime}``).

Threads
-------
- **one thread per source**, iterating ``generate()``. A live source (``live = True``)
  stamps its samples with ``self.now_ns()``, which the executor points at one shared
  :class:`~impala_flow._clock.MissionClock`: every sensor has the same mission time base.
  A non-live source used live (a replayer, a simulator) is *paced*: its samples are
  released when the mission clock reaches them and re-stamped on the mission clock, the
  earliest first sample of all non-live sources being mapped to the start of the run
  (so several non-live sources stay aligned with each other).
- **a worker pool** runs the components. Each component has a *mailbox* (the triggers
  waiting for it) and a *scheduled* flag, both guarded by the component's lock: a
  component is in the pool's ready queue at most once and is drained serially by one
  worker at a time, so ``process`` never runs concurrently with itself, while different
  components run in parallel (numpy/OpenCV release the GIL). A worker runs at most
  ``BATCH`` triggers of one component before putting it back at the end of the ready
  queue, for fairness. The pool has, by default, one thread per component that can be
  triggered: with the ``block`` overflow policy a ``process`` call can wait inside
  ``emit`` for room downstream, and a smaller pool could then starve the consumer it is
  waiting for (pass ``workers=`` to cap it when no input blocks).
- **a timer thread** (only when some component declares :class:`~impala_flow._component.Periodic`
  timers) puts timer triggers in the mailboxes at every multiple of the period on
  mission time; ``process(t)`` receives that multiple. A tick still waiting in the mailbox
  when the next one is due is not queued twice: it is counted as ``missed_ticks`` in the
  component's summary.

Locks and ports
---------------
Each component has one ``threading.RLock``; each of its inputs gets
``InputPort._cond = threading.Condition(that lock)``. Delivering a sample pushes it into
the input *under the owner's lock* and, when ``push`` says the owner must run (reactive
input, completed sync group), appends a trigger to the mailbox and schedules the
component. With the ``block`` policy a full input makes ``push`` wait on the condition,
which releases the lock so the consumer can ``take()``; ``take()`` pops and notifies
under the same lock. ``drop_oldest`` / ``drop_newest`` count their drops in the port's
stats, which the run summary reports exactly as the offline executor does. A reactive
trigger is resolved when it is run (the time passed to ``process`` is that of the sample
at the head of the input), so a trigger whose sample was dropped by ``drop_oldest`` is
skipped, never run on an empty input. Delayed connections (``[delay]``) only break cycles
for validation; in real time every sample is delivered at once. A component that feeds
its own input with ``block`` (directly or around a cycle of full inputs) deadlocks: give
such loops a drop policy.

Clock offsets
-------------
A source may declare the offset of its clock with respect to the mission clock (a GPS
receiver's time vs the radar's): a ``Param`` or plain attribute ``clock_offset_ns``
(int ns). The executor adds it to every timestamp the source yields, on the way in, so
every downstream component and the recorder see corrected times. The offsets used are
listed in ``network.metadata["clock_offsets_ns"]`` and in the run summary (``extra``).

Stop sequence
-------------
The run ends when all sources are exhausted and every mailbox is drained (no component
scheduled; timers do not keep a graph alive, except in a graph that has timers and no
source at all, which runs until stopped), when ``stop_event`` is set (``Session`` turns SIGINT/SIGTERM into it; a
``KeyboardInterrupt`` reaching the calling thread does the same) or when a component
raises. Then, in this order:

1. sources stop taking samples (each is told with ``Source.request_stop()``, so one waiting
   on a device leaves at its next poll; their generators are closed in their own thread; a
   source still inside ``generate()`` after ``stop_timeout_s`` is abandoned, with a
   warning) and the timers stop;
2. after an interrupt, the samples already delivered are still processed (up to
   ``drain_timeout_s``), so nothing acquired is lost; after an error, nothing new starts;
   at a normal end (all sources exhausted), each component's ``flush(t)`` then runs, in
   graph order, and what it emits is drained before the next one's;
3. the mailboxes are closed: ``process`` calls in flight finish, samples still queued
   are discarded and any producer waiting for room is released. Samples never taken
   (queued at that point or delivered later) are counted as ``unconsumed`` (``unmatched``
   for sync groups), like the offline executor's leftovers: nothing is lost silently.
   ``dropped`` only ever counts the overflow policies' drops;
4. the workers are joined, then ``stop()`` runs exactly once for every component whose
   ``start()`` was called (also one whose ``start()`` raised), in graph order, on the
   calling thread; ``summary()`` is asked only of those whose ``start()`` returned;
5. the summary is completed (``interrupted`` flag, drops, per-component counts), and a
   :class:`~impala_flow._summary.ComponentError` is raised if a component failed, with
   the summary attached as ``error.summary``. It is the first failure; later ones (another
   component, a ``stop()`` or ``summary()`` that raised) are lines of ``summary.errors``.
   Steps 4 and 5 (and starting the components in graph order) are the lifecycle both
   executors share (:mod:`impala_flow._lifecycle`).

Duration, time per call, latency
--------------------------------
``duration_ns`` ends the run like the end of the inputs (sources stop, step 2 with the
flush) once the mission clock has run that long; ``summary.stopped_at_duration`` says so.
Every ``process`` call is timed (``time.perf_counter_ns``) into the component's histogram, and
every sample carries the origin of its work (``Sample.entered_ns``: a source's sample its arrival
on the mission clock, a component's emission the origin of the sample that triggered the call,
set per worker thread; a component that holds work for later sets it back with
``Component.work_origin_ns``); its first delivery records ``now - origin`` per output. Both go to the
summary (``timing``, ``latency``; :mod:`impala_flow._timing`): about 1 us per call and per
emitted sample, memory bounded by the histograms' buckets.

Equal timestamps: samples are delivered as they come; the executor cannot wait for a
sample that may never arrive, so the offline equal-timestamp rule (see
:mod:`impala_flow._offline`) is not guaranteed live: read equal-time streams through a sync
group or ``at(t, clamp=True)``. A ``block`` input that makes its producer wait counts the
waits and their duration (``blocked``, ``blocked_ns``: BACKPRESSURE in the summary).
Timestamps outside int64 are refused at the source, as offline.

A component listed with ``on_error: skip`` in ``network.on_error`` has its failing calls
counted (``skipped``) instead, the first few logged (:func:`~impala_flow._summary.log_skip`);
a failing source then just ends.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from typing import Any, Protocol

from ._clock import MissionClock
from ._component import Component, Source
from ._lifecycle import Lifecycle, check_source_time
from ._native import check_blas_threads
from ._network import Network
from ._ports import InputPort, SyncGroup
from ._sample import Sample
from ._summary import ComponentError, RunSummary, log_skip
from ._timing import Histogram, latency_figures, timing_figures

__all__ = ["RealTimeExecutor", "run_realtime", "BATCH"]

log = logging.getLogger("impala_flow.runtime")  # the name logs have always used

ProgressFn = Callable[[int, int | None], None]

#: triggers a worker runs for one component before letting the others have the worker
BATCH = 32

_IN, _SYNC, _TIMER = 0, 1, 2


class _Clock(Protocol):
    def now_ns(self) -> int: ...


class _State:
    """Mailbox and bookkeeping of one triggerable component (guarded by ``lock``)."""

    __slots__ = (
        "comp", "lock", "mailbox", "scheduled", "halted", "skip", "count", "skipped", "delivered",
        "unconsumed", "timers_pending", "missed_ticks", "hist",
    )

    def __init__(self, comp: Component, skip: bool) -> None:
        self.comp = comp
        self.lock = threading.RLock()
        self.mailbox: deque[tuple[int, Any, int]] = deque()
        self.scheduled = False
        self.halted = False
        self.skip = skip
        self.count = 0
        self.skipped = 0
        self.delivered = 0
        self.unconsumed: dict[InputPort, int] = {}  # reactive samples discarded at stop
        self.timers_pending: set[str] = set()
        self.missed_ticks = 0
        self.hist = Histogram()  # time per process call


class _SourceRun:
    __slots__ = ("src", "thread", "emitted", "done", "first", "offset", "gen")

    def __init__(self, src: Source, offset: int) -> None:
        self.src = src
        self.offset = offset
        self.gen: Iterator[tuple[int, str, Any]] | None = None
        self.thread: threading.Thread | None = None
        self.emitted = 0
        self.done = False
        self.first: tuple[int, str, Any] | None = None  # prefetched first item (non-live)


class RealTimeExecutor:
    """Runs a :class:`Network` live (see the module docstring).

    ``stop_event`` ends the run cleanly; ``progress(now_ns, start_ns)`` is called from the
    calling thread every ``progress_interval_s``; ``clock`` (anything with ``now_ns()``)
    defaults to a fresh :class:`MissionClock`; ``workers`` sizes the pool (default: one
    per triggerable component). ``duration_ns`` ends the run after that much mission (here:
    wall) time as at the end of the inputs: the sources stop, what they delivered is processed
    and every component flushed (``summary.stopped_at_duration``; an interrupt does not flush).
    ``blas_threads``: the BLAS libraries' own threads while the components run
    (:mod:`impala_flow._native`; None: the libraries' own).
    """

    def __init__(
        self, network: Network, stop_event: threading.Event | None = None,
        progress: ProgressFn | None = None, clock: _Clock | None = None, workers: int | None = None,
        *, drain_timeout_s: float = 2.0, stop_timeout_s: float = 5.0, progress_interval_s: float = 0.25,
        duration_ns: int | None = None, blas_threads: int | None = 1,
    ) -> None:
        if workers is not None and workers < 1:
            raise ValueError("workers must be >= 1")
        self.blas_threads = check_blas_threads(blas_threads)
        if duration_ns is not None and duration_ns <= 0:
            raise ValueError(f"duration_ns must be > 0, got {duration_ns}")
        self.duration_ns = duration_ns
        self.net = network
        self.stop_event = stop_event or threading.Event()
        self.progress = progress
        self.clock: _Clock = clock or MissionClock()
        self.workers = workers
        self.drain_timeout_s = drain_timeout_s
        self.stop_timeout_s = stop_timeout_s
        self.progress_interval_s = progress_interval_s
        self.summary = RunSummary(graph=network.name)
        self._ready: queue.SimpleQueue[_State | None] = queue.SimpleQueue()
        self._tick = itertools.count()
        self._wake = threading.Event()  # something the calling thread should look at
        self._stopping = threading.Event()  # sources stop
        self._timers_stop = threading.Event()
        self._error: ComponentError | None = None
        self._later: list[ComponentError] = []  # failures after the first, reported on their own lines
        self._error_lock = threading.Lock()
        self._states: list[_State] = []
        self._timer_ticks = 0
        self._source_skips: dict[str, int] = {}
        self._origin = threading.local()  # origin_ns: the origin of the sample a worker's process() handles
        self._latency: dict[str, Histogram] = {}  # "component.output" -> emit - origin

    # --- errors ---------------------------------------------------------------------
    def _fail(self, err: ComponentError) -> None:
        with self._error_lock:
            if self._error is None:
                self._error = err
            else:
                self._later.append(err)
        self._stopping.set()
        self._wake.set()

    # --- scheduling -----------------------------------------------------------------
    def _schedule_locked(self, st: _State, entry: tuple[int, Any, int]) -> None:
        """Append ``entry`` to the mailbox and make sure the component will run (lock held)."""
        st.mailbox.append(entry)
        if not st.scheduled:
            st.scheduled = True
            next(self._tick)
            self._ready.put(st)

    def _worker(self) -> None:
        ready = self._ready
        while True:
            st = ready.get()
            if st is None:
                return
            try:
                self._drain(st)
            except BaseException as e:  # never lose a worker silently
                self._fail(ComponentError(st.comp.name, st.comp.trigger, None, "process", e))
                with st.lock:
                    st.scheduled = False

    def _drain(self, st: _State) -> None:
        comp, lock, mailbox = st.comp, st.lock, st.mailbox
        tl, pc, hist = self._origin, time.perf_counter_ns, st.hist
        n = 0
        while True:
            with lock:
                if st.halted or not mailbox:
                    st.scheduled = False
                    return
                if n >= BATCH:  # let the others have this worker; stay scheduled
                    self._ready.put(st)
                    return
                kind, obj, t = mailbox.popleft()
                if kind == _IN:
                    fifo = obj._fifo
                    if not fifo:
                        continue  # its sample was dropped (drop_oldest) or taken already
                    t = fifo[0].timestamp
                    origin = fifo[0].entered_ns
                    trig = obj.trigger_name
                elif kind == _SYNC:
                    cur = [m._current for m in obj.members]
                    if any(s is None for s in cur):
                        continue
                    t = max(s.timestamp for s in cur)  # type: ignore[union-attr]
                    origin = max((s.entered_ns for s in cur if s.entered_ns is not None),  # type: ignore[union-attr]
                                 default=None)
                    trig = obj.name
                else:
                    trig = obj
                    origin = t  # a timer: its tick's time
                    st.timers_pending.discard(obj)
            n += 1
            comp.trigger = trig
            tl.origin_ns = origin
            t0 = pc()
            try:
                comp.process(t)
            except Exception as e:
                if st.skip:
                    st.skipped += 1
                    if st.skipped == 1:
                        self.summary.first_skip[comp.name] = f"t={t} ns: {type(e).__name__}: {e}"
                    log_skip(comp.log, st.skipped, t, e)
                else:
                    err = ComponentError(comp.name, trig, t, "process", e)
                    err.__cause__ = e
                    self._fail(err)
                    with lock:
                        st.scheduled = False
                    return
            else:
                st.count += 1
            finally:
                hist.add(pc() - t0)
                tl.origin_ns = None
            if kind == _SYNC:  # samples that arrived while the match was pending
                with lock:
                    if obj.match():
                        self._schedule_locked(st, (_SYNC, obj, 0))

    def _quiescent(self) -> bool:
        """True when no component is scheduled and none got scheduled during the check."""
        c0 = next(self._tick)
        for st in self._states:
            if st.scheduled:
                return False
        return next(self._tick) == c0 + 1

    # --- sources --------------------------------------------------------------------
    def _source_loop(self, run: _SourceRun, base_ns: int, first_ns: int | None) -> None:
        src, offset = run.src, run.offset
        outs = src.outputs
        now = self.clock.now_ns
        stopping = self._stopping
        paced = not src.live
        last_t: int | None = None
        port = "generate"
        try:
            if run.gen is None:
                run.gen = iter(src.generate())
            gen = run.gen
            item, run.first = run.first, None
            while not stopping.is_set():
                if item is None:
                    item = next(gen, None)
                    if item is None or stopping.is_set():  # a late sample of an abandoned source
                        break
                t, port, data = item
                item = None
                if type(t) is not int:
                    t = int(t)
                if not -(1 << 63) <= t + offset < 1 << 63:
                    check_source_time(src.name, port, t + offset)
                if last_t is not None and t < last_t:
                    raise ValueError(f"source yielded t={t} ns after t={last_t} ns: samples must come in time order")
                last_t = t
                if paced:
                    t = base_ns + (t - first_ns)  # type: ignore[operator]
                    delay = t - now()
                    if delay > 0 and stopping.wait(delay / 1e9):
                        break
                t += offset
                out = outs.get(port)
                if out is None:
                    raise KeyError(f"yielded a sample for unknown output '{port}' "
                                   f"(outputs: {', '.join(outs) or 'none'})")
                out.emit(t, data)
                run.emitted += 1
        except ComponentError as e:
            self._fail(e)
        except Exception as e:
            if self.net.on_error.get(src.name) == "skip":
                src.log.warning("source ended after %s: %s", type(e).__name__, e)
                self._source_skips[src.name] = self._source_skips.get(src.name, 0) + 1
            else:
                err = ComponentError(src.name, port, last_t, "generate", e)
                err.__cause__ = e
                self._fail(err)
        finally:
            close = getattr(run.gen, "close", None)
            if close is not None:
                try:
                    close()
                except Exception as e:  # a generator's cleanup failing is still reported
                    self._fail(ComponentError(src.name, "generate", last_t, "generate", e))
            run.done = True
            self._wake.set()

    # --- timers ---------------------------------------------------------------------
    def _timer_loop(self, timers: list[tuple[_State, str, int]]) -> None:
        now = self.clock.now_ns
        t0 = now()
        heap = []
        for i, (st, name, p) in enumerate(timers):
            heap.append((-(-t0 // p) * p, i, st, name, p))
        heapq.heapify(heap)
        stop = self._timers_stop
        while heap and not stop.is_set():
            due, i, st, name, p = heap[0]
            delay = due - now()
            if delay > 0:
                if stop.wait(delay / 1e9):
                    return
                continue
            late = now() - due
            missed = late // p  # ticks that passed while we were late: skipped, counted
            heapq.heapreplace(heap, (due + (missed + 1) * p, i, st, name, p))
            with st.lock:
                st.missed_ticks += missed
                if st.halted:
                    continue
                if name in st.timers_pending:
                    st.missed_ticks += 1
                    continue
                st.timers_pending.add(name)
                self._timer_ticks += 1
                self._schedule_locked(st, (_TIMER, name, due))

    # --- the run --------------------------------------------------------------------
    def run(self) -> RunSummary:
        """Start the components (in graph order), the workers, the timer thread and one
        thread per source; wait for the end (sources done and nothing scheduled, a stop, an
        error); shut down, flush, stop; return the summary or raise the first error."""
        net = self.net
        # start, stop, errors, counters, the BLAS limit: shared with the offline executor
        life = Lifecycle(net, self.summary, self.blas_threads)
        order = life.order  # as offline: ties by component id, never by YAML order
        summary = self.summary
        states = self._wire(order)
        sources = [_SourceRun(c, int(getattr(c, "clock_offset_ns", 0) or 0)) for c in order if isinstance(c, Source)]
        offsets = {r.src.name: r.offset for r in sources if r.offset}
        if offsets:
            net.metadata["clock_offsets_ns"] = dict(offsets)
        workers: list[threading.Thread] = []
        timers: list[threading.Thread] = []  # the timer thread, when a component has timers
        life.wall0 = time.perf_counter()
        try:
            life.start()
            first_ns = self._prime(sources)
            self._launch(order, states, sources, first_ns, workers, timers)
            self._wait(sources, summary.mission_start_ns or 0, endless=not sources and bool(timers))
        except ComponentError as e:
            self._fail(e)
        except KeyboardInterrupt:
            summary.interrupted = True
        finally:
            if self.stop_event.is_set():
                summary.interrupted = True
            self._shutdown(sources, workers, timers[0] if timers else None, [] if summary.interrupted else order)
            error = self._finish(life, states, sources, offsets)
            self._unwire(order)
            if self.progress is not None and summary.mission_end_ns is not None:
                self.progress(summary.mission_end_ns, summary.mission_start_ns)
        return life.result(error)

    def _wire(self, order: list[Component]) -> dict[str, _State]:
        """A mailbox (:class:`_State`) per component that can be triggered, every output
        delivering through it, every component's ``now_ns()`` on the mission clock."""
        now = self.clock.now_ns
        skip = {name for name, pol in self.net.on_error.items() if pol == "skip"}
        states: dict[str, _State] = {}
        route: dict[InputPort, tuple[_State, tuple[int, Any, int]]] = {}
        for c in order:
            c._clock_ns = now
            c._origin_tl = self._origin
            if c.inputs or c.__timers__:
                st = states[c.name] = _State(c, c.name in skip)
                groups: dict[SyncGroup, tuple[int, Any, int]] = {g: (_SYNC, g, 0) for g in c.sync_groups.values()}
                for inp in c.inputs.values():
                    inp._cond = threading.Condition(st.lock)
                    route[inp] = (st, groups[inp.group] if inp.group is not None else (_IN, inp, 0))
        self._states = list(states.values())
        schedule = self._schedule_locked
        tl, latency = self._origin, self._latency

        def deliver(inp: InputPort, s: Sample, delayed: bool) -> None:
            if s.entered_ns is None:  # its first delivery: where its origin is set, and its latency taken
                origin = getattr(tl, "origin_ns", None)
                arrived = now()
                if origin is None:  # a source's sample (or one emitted outside process()): it enters now
                    s.entered_ns = arrived
                else:
                    s.entered_ns = origin
                    h = latency.get(s.origin)
                    if h is None:
                        h = latency[s.origin] = Histogram()
                    h.add(arrived - origin)
            st, entry = route[inp]
            with st.lock:
                if st.halted:  # closing: counted, never silently lost
                    inp.stats.received += 1
                    if inp.group is not None:
                        inp.stats.unmatched += 1
                    elif inp.policy == "reactive":
                        st.unconsumed[inp] = st.unconsumed.get(inp, 0) + 1
                    return
                st.delivered += 1
                if inp.push(s):
                    schedule(st, entry)

        for c in order:
            for out in c.outputs.values():
                out._deliver = deliver
        return states

    @staticmethod
    def _unwire(order: list[Component]) -> None:
        """Leave the ports as the offline executor expects them."""
        for c in order:
            for inp in c.inputs.values():
                inp._cond = None
            for out in c.outputs.values():
                out._deliver = None

    @staticmethod
    def _prime(sources: list[_SourceRun]) -> int | None:
        """Pull the first sample of every non-live source (to align them); return the
        earliest time (None when none has one)."""
        first_ns: int | None = None
        for r in sources:
            if r.src.live:
                continue
            try:
                r.gen = iter(r.src.generate())
                r.first = next(r.gen, None)
            except Exception as e:
                raise ComponentError(r.src.name, "generate", None, "generate", e) from e
            if r.first is None:
                r.done = True
                close = getattr(r.gen, "close", None)
                if close is not None:
                    close()
            else:
                t = int(r.first[0])
                first_ns = t if first_ns is None else min(first_ns, t)
        return first_ns

    def _launch(self, order: list[Component], states: dict[str, _State], sources: list[_SourceRun],
                first_ns: int | None, workers: list[threading.Thread], timers: list[threading.Thread]) -> None:
        """Start the worker pool, the mission clock (``summary.mission_start_ns``), the timer
        thread and the source threads; ``workers`` and ``timers`` get the threads as they start."""
        for i in range(self.workers or max(1, len(self._states))):
            th = threading.Thread(target=self._worker, name=f"impala-worker-{i}", daemon=True)
            th.start()
            workers.append(th)
        start_ns = self.clock.now_ns()
        self.summary.mission_start_ns = start_ns
        periodic = [(states[c.name], name, tm.period_ns(c)) for c in order if c.name in states
                    for name, tm in c.__timers__.items()]
        if periodic:
            th = threading.Thread(target=self._timer_loop, args=(periodic,), name="impala-timers", daemon=True)
            th.start()
            timers.append(th)
        for r in sources:
            if r.done:
                continue
            r.thread = threading.Thread(target=self._source_loop, args=(r, start_ns, first_ns),
                                        name=f"impala-source-{r.src.name}", daemon=True)
            r.thread.start()

    def _finish(self, life: Lifecycle, states: dict[str, _State], sources: list[_SourceRun],
                offsets: dict[str, int]) -> ComponentError | None:
        """The executor's figures (events, calls, skips, missed ticks, samples discarded at
        stop) handed to the shared lifecycle; return the error to raise."""
        summary = self.summary
        summary.mission_end_ns = self.clock.now_ns() if summary.mission_start_ns is not None else None
        summary.events = (sum(r.emitted for r in sources) + sum(st.delivered for st in self._states)
                          + self._timer_ticks)
        skipped = {st.comp.name: st.skipped for st in self._states if st.skipped}
        skipped.update(self._source_skips)
        extra: dict[str, dict[str, Any]] = {name: {"clock_offset_ns": off} for name, off in offsets.items()}
        for st in self._states:
            if st.missed_ticks:
                extra.setdefault(st.comp.name, {})["missed_ticks"] = st.missed_ticks
        removed = {inp: n for st in self._states for inp, n in st.unconsumed.items()}
        error = life.finish(self._error, earlier=self._later,
                            processed={c.name: states[c.name].count if c.name in states else 0 for c in life.order},
                            skipped=skipped, unconsumed=removed, extra=extra)
        summary.timing = timing_figures({st.comp.name: st.hist for st in self._states}, summary.wall_s)
        summary.latency = latency_figures(dict(self._latency))
        return error

    def _wait(self, sources: list[_SourceRun], start_ns: int, endless: bool) -> None:
        """Block the calling thread until the run should end (``endless``: only on a stop)."""
        wake, stop = self._wake, self.stop_event
        last_progress = time.perf_counter()
        end_ns = None if self.duration_ns is None else start_ns + self.duration_ns
        self.summary.duration_s = None if self.duration_ns is None else self.duration_ns / 1e9
        while True:
            all_done = all(r.done for r in sources)
            wake.wait(0.01 if all_done else 0.05)
            wake.clear()
            if stop.is_set():
                self.summary.interrupted = True
                return
            if end_ns is not None and self.clock.now_ns() >= end_ns and self._error is None:
                self.summary.stopped_at_duration = True  # an end of the inputs: flushed, not interrupted
                return
            if self._error is not None:
                return
            if not endless and all(r.done for r in sources) and self._quiescent():
                return
            if self.progress is not None:
                t = time.perf_counter()
                if t - last_progress >= self.progress_interval_s:
                    last_progress = t
                    self.progress(self.clock.now_ns(), start_ns)

    def _shutdown(self, sources: list[_SourceRun], workers: list[threading.Thread],
                  timer_thread: threading.Thread | None, flush: list[Component]) -> None:
        """Stop sources and timers, drain, ``flush`` the given components (graph order,
        each one's consequences drained before the next), close mailboxes, join workers."""
        self._stopping.set()
        self._timers_stop.set()
        for r in sources:
            if r.thread is not None and r.thread.is_alive():
                try:
                    r.src.request_stop()
                except Exception as e:  # a source's own failure to stop must not hide the run's result
                    log.warning("source '%s': request_stop() raised %s: %s", r.src.name, type(e).__name__, e)
        deadline = time.monotonic() + self.stop_timeout_s
        for r in sources:
            if r.thread is not None:
                r.thread.join(max(0.0, deadline - time.monotonic()))
                if r.thread.is_alive():
                    log.warning("source '%s' did not leave generate() within %.1f s: abandoned",
                                r.src.name, self.stop_timeout_s)
        if timer_thread is not None:
            timer_thread.join(self.stop_timeout_s)
        self._drain_all(workers)
        for c in flush if self._error is None else []:
            if type(c).flush is Component.flush:
                continue
            st = next((x for x in self._states if x.comp is c), None)
            t = self.clock.now_ns()
            try:
                if st is not None:
                    with st.lock:
                        c.flush(t)
                else:
                    c.flush(t)
            except Exception as e:
                self._fail(ComponentError(c.name, "flush", t, "flush", e))
                break
            self._drain_all(workers)
        # close the mailboxes: in-flight calls finish, queued samples are counted as dropped
        self._halt()
        for _ in workers:
            self._ready.put(None)
        deadline = time.monotonic() + self.stop_timeout_s
        for th in workers:
            while th.is_alive() and time.monotonic() < deadline:
                th.join(0.05)
                if th.is_alive():
                    self._halt()  # release a producer that started waiting since
            if th.is_alive():
                log.warning("%s still inside process() after %.1f s: abandoned", th.name, self.stop_timeout_s)

    def _drain_all(self, workers: list[threading.Thread]) -> None:
        if self._error is None and workers:
            drain_end = time.monotonic() + self.drain_timeout_s
            while not self._quiescent() and time.monotonic() < drain_end and self._error is None:
                time.sleep(0.002)

    def _halt(self) -> None:
        for st in self._states:
            with st.lock:
                st.halted = True
                st.mailbox.clear()
                st.timers_pending.clear()
                for inp in st.comp.inputs.values():
                    n = len(inp._fifo)
                    if n:  # never taken: reported as unconsumed (sync members: unmatched)
                        inp._fifo.clear()
                        if inp.group is not None:
                            inp.stats.unmatched += n
                        else:
                            st.unconsumed[inp] = st.unconsumed.get(inp, 0) + n
                    if inp._cond is not None:
                        inp._cond.notify_all()


def run_realtime(network: Network, **kw: Any) -> RunSummary:
    """Run ``network`` on the real-time executor (keywords as :class:`RealTimeExecutor`)."""
    return RealTimeExecutor(network, **kw).run()
