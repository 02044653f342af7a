"""Engine hardening (issue 11): the first error always reaches the user (4), declared output
types are enforced (6), equal timestamps do not depend on path length or YAML order (7),
and failed, interrupted, blocked and skipping runs say what happened (13)."""

from __future__ import annotations

import itertools
import logging
import re
import threading
import time

import numpy as np
import pytest

from impala_flow import Component, ComponentError, Input, Network, OfflineExecutor, Output, Param, Source
from impala_flow._ports import OutputPort
from impala_flow._realtime import RealTimeExecutor
from impala_flow._summary import SKIP_LOG_LIMIT
from impala_flow.testing import CollectingSink, ScriptedSource, connect, run_graph_text

from .components import Boom, Counter

MS = 1_000_000


def _net(*comps: Component, connections: list[str], on_error: dict[str, str] | None = None) -> Network:
    net = Network()
    for c in comps:
        net.add(c, on_error=(on_error or {}).get(c.name, "stop"))
    for spec in connections:
        connect(net, spec)
    return net


# --- 4. the first error is never hidden ---------------------------------------------------------
class StartFails(Component):
    x = Input(float)

    def start(self) -> None:
        self.stopped = False
        raise OSError("device /dev/radar0 not found")

    def stop(self) -> None:
        self.stopped = True


class NeedsStart(Component):
    """Its summary() and stop() only work after start(): like most real components."""

    x = Input(float)

    def start(self) -> None:
        self.seen = 0

    def process(self, t: int) -> None:
        self.x.take()
        self.seen += 1

    def summary(self) -> dict:
        return {"seen": self.seen}


class BadSummary(NeedsStart):
    def summary(self) -> dict:
        raise KeyError("figure")


class BadStop(NeedsStart):
    def stop(self) -> None:
        raise RuntimeError("could not close the report")


@pytest.mark.parametrize("executor", [OfflineExecutor, RealTimeExecutor])
def test_start_error_is_raised_not_the_summary_of_a_component_never_started(executor) -> None:
    src, bad, late = Counter("src", n=3), StartFails("bad"), NeedsStart("late")
    net = _net(src, bad, late, connections=["src.out -> bad.x", "src.out -> late.x"])
    with pytest.raises(ComponentError) as ei:
        executor(net).run()
    assert str(ei.value) == "component 'bad', in start(): OSError: device /dev/radar0 not found"
    assert bad.stopped  # stop() runs on the component whose start() raised, to release what it took
    summary = ei.value.summary
    assert summary.error == str(ei.value) and summary.errors == []
    assert "late" not in summary.extra  # never started: its summary() is not asked


@pytest.mark.parametrize("executor", [OfflineExecutor, RealTimeExecutor])
def test_stop_and_summary_failures_are_their_own_lines_after_the_first_error(executor) -> None:
    src, boom = Counter("src", n=6, period_ns=1_000), Boom("boom", at=3.0)
    summ, stop = BadSummary("summ"), BadStop("stopper")
    net = _net(src, boom, summ, stop, connections=["src.out -> boom.x", "src.out -> summ.x", "src.out -> stopper.x"])
    with pytest.raises(ComponentError) as ei:
        executor(net).run()
    # (the real-time executor stamps on the mission clock)
    assert re.fullmatch(r"component 'boom', input 'x', sample t=\d+ ns: ValueError: bad value 3.0", str(ei.value))
    s = ei.value.summary
    assert sorted(s.errors) == ["component 'stopper', in stop(): RuntimeError: could not close the report",
                                "component 'summ', in summary(): KeyError: 'figure'"]
    text = s.format().splitlines()
    assert text[0].endswith("FAILED: " + str(ei.value))
    assert "  ERROR component 'stopper', in stop(): RuntimeError: could not close the report" in text
    assert boom.stopped


def test_a_summary_failure_alone_fails_the_run_naming_its_component() -> None:
    net = _net(Counter("src", n=2), BadSummary("summ"), connections=["src.out -> summ.x"])
    with pytest.raises(ComponentError, match=r"^component 'summ', in summary\(\): KeyError: 'figure'$"):
        OfflineExecutor(net).run()


# --- 6. declared output types ------------------------------------------------------------------
class Emits(Component):
    """Emits on a float output whatever value it is given for each sample index."""

    x = Input(float)
    y = Output(float)
    values = Param(list, default=[])

    def process(self, t: int) -> None:
        i = int(self.x.take())
        self.y.emit(t, self.values[i])


def test_a_wrong_output_type_names_the_producer_port_and_time() -> None:
    emits = Emits("gain", values=[1.0, 2, np.float32(3.5), "4.0"])
    sink = CollectingSink("sink")
    net = _net(Counter("src", n=4, period_ns=10), emits, sink, connections=["src.out -> gain.x", "gain.y -> sink.x"])
    with pytest.raises(ComponentError) as ei:
        OfflineExecutor(net).run()
    assert str(ei.value) == ("component 'gain', input 'x', sample t=30 ns: OutputTypeError: output 'y' of "
                             "component 'gain' is declared float but emitted str '4.0' at t=30 ns")
    assert sink.values() == [1.0, 2, np.float32(3.5)]  # ints and numpy floats are numbers too


def test_a_source_emitting_the_wrong_type_is_named() -> None:
    class Src(Source):
        out = Output(float)

        def generate(self):
            yield 0, "out", 1.0
            yield 5, "out", True  # a bool is not a float

    net = _net(Src("gps"), CollectingSink("sink"), connections=["gps.out -> sink.x"])
    with pytest.raises(ComponentError) as ei:
        OfflineExecutor(net).run()
    assert str(ei.value) == ("component 'gps', in generate(): OutputTypeError: output 'out' of component 'gps' "
                             "is declared float but emitted bool True at t=5 ns")


def test_the_type_check_runs_once_per_class_and_port(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[type] = []
    real = OutputPort._check_type

    def counting(self, t_ns, data):  # type: ignore[no-untyped-def]
        calls.append(type(data))
        return real(self, t_ns, data)

    monkeypatch.setattr(OutputPort, "_check_type", counting)
    values = [1.0, 2.0, 3, 4.0, 5, np.float64(6.0)] * 5
    emits = Emits("gain", values=values)
    net = _net(Counter("src", n=len(values), period_ns=10), emits, CollectingSink("sink"),
               connections=["src.out -> gain.x", "gain.y -> sink.x"])
    OfflineExecutor(net).run()
    # gain.y sees float, int, np.float64; the Counter's own float output one class
    assert sorted(c.__name__ for c in calls) == ["float", "float", "float64", "int"]


def test_realtime_enforces_output_types_too() -> None:
    emits = Emits("gain", values=[1.0, [2.0]])
    net = _net(Counter("src", n=2, period_ns=1_000), emits, CollectingSink("sink"),
               connections=["src.out -> gain.x", "gain.y -> sink.x"])
    with pytest.raises(ComponentError, match=r"output 'y' of component 'gain' is declared float but emitted list"):
        RealTimeExecutor(net).run()


# --- 7. equal timestamps: path length and YAML order --------------------------------------------
class Poses(Source):
    """At every 10 ms: a pose x = t in ms and a trigger, in the order given by ``pose_first``."""

    pose = Output(float)
    trig = Output(float)
    n = Param(int, default=5)
    pose_first = Param(bool, default=True)

    def generate(self):
        for i in range(self.n):
            t = i * 10 * MS
            items = [(t, "pose", float(i * 10)), (t, "trig", float(i))]
            yield from (items if self.pose_first else items[::-1])


class Hop(Component):
    x = Input(float)
    y = Output(float)

    def process(self, t: int) -> None:
        self.y.emit(t, self.x.take())


class AtPose(Component):
    """On each trigger, the pose at the trigger's time from a history input."""

    trig = Input(float)
    pose = Input(float, policy="sampling", history=1.0)
    out = Output(float)

    def process(self, t: int) -> None:
        self.trig.take()
        self.out.emit(t, self.pose.at(t))


def _chain_graph(hops: int, pose_first: bool, order: tuple[int, ...]) -> str:
    comps = [f"  src: {{type: t.Poses, params: {{pose_first: {str(pose_first).lower()}}}}}",
             "  at: {type: t.AtPose}", "  sink: {type: t.CollectingSink}"]
    comps += [f"  hop{i}: {{type: t.Hop}}" for i in range(hops)]
    conns = [f"  - hop{i}.y -> " + (f"hop{i + 1}.x" if i + 1 < hops else "at.pose") for i in range(hops)]
    conns += ["  - src.pose -> " + ("hop0.x" if hops else "at.pose"), "  - src.trig -> at.trig", "  - at.out -> sink.x"]
    comps = [comps[i] for i in order] if len(order) == len(comps) else comps
    return "name: chain\ncomponents:\n" + "\n".join(comps) + "\nconnections:\n" + "\n".join(reversed(conns)) + "\n"


@pytest.mark.parametrize("hops", [0, 1, 2, 4])
@pytest.mark.parametrize("pose_first", [True, False])
def test_history_input_holds_the_sample_of_the_trigger_time_whatever_the_path(hops: int, pose_first: bool) -> None:
    n_comps = 3 + hops
    orders = [tuple(range(n_comps)), tuple(reversed(range(n_comps)))]
    if n_comps <= 5:
        orders = list(itertools.permutations(range(n_comps)))[:24]
    results = set()
    for order in orders:
        summary, net = run_graph_text(_chain_graph(hops, pose_first, order), Poses, Hop, AtPose, CollectingSink,
                                      plugin="t")
        sink = net.components["sink"]
        # the pose stamped t is x = t in ms, exactly: at(t) returns it (no interpolation)
        assert sink.values() == [0.0, 10.0, 20.0, 30.0, 40.0]
        assert sink.times() == [0, 10 * MS, 20 * MS, 30 * MS, 40 * MS]
        results.add((tuple(sink.values()), tuple(sink.times()), summary.events))
    assert len(results) == 1  # bit-identical whatever the YAML order


class Log(Component):
    """Records (trigger, value) for every call, across two reactive inputs."""

    a = Input(float)
    b = Input(float)

    def start(self) -> None:
        self.calls: list[tuple[str, float, int]] = []

    def process(self, t: int) -> None:
        self.calls.append((self.trigger, self.inputs[self.trigger].take(), t))


def test_equal_time_samples_from_independent_producers_reach_a_component_in_the_same_order() -> None:
    script = [(t, "out", float(t)) for t in (0, 0, 5, 10)]
    runs = set()
    for names in itertools.permutations(["p", "q", "log"]):
        net = Network()
        for nm in names:
            net.add(ScriptedSource(nm, [(t, p, v + (100 if nm == "q" else 0)) for t, p, v in script])
                    if nm != "log" else Log("log"))
        connect(net, "p.out -> log.a")
        connect(net, "q.out -> log.b")
        OfflineExecutor(net).run()
        runs.add(tuple(net.components["log"].calls))
    (calls,) = runs
    # every sample of a time arrives before the first call of that time; producers ranked by id (p < q)
    assert [c[:2] for c in calls] == [("a", 0.0), ("a", 0.0), ("b", 100.0), ("b", 100.0), ("a", 5.0),
                                       ("b", 105.0), ("a", 10.0), ("b", 110.0)]


def test_a_sync_group_completed_several_times_at_one_time_fires_for_each_match() -> None:
    class Pair(Component):
        a = Input(float, sync="s", tolerance=0.0)
        b = Input(float, sync="s", tolerance=0.0)
        out = Output(float)

        def process(self, t: int) -> None:
            self.out.emit(t, self.a.take() * 10 + self.b.take())

    src = ScriptedSource("src", [(0, "a", 1.0), (0, "a", 2.0), (0, "b", 3.0), (0, "b", 4.0), (7, "a", 5.0),
                                 (7, "b", 6.0)])
    sink = CollectingSink("sink")
    net = _net(src, Pair("pair"), sink, connections=["src.a -> pair.a", "src.b -> pair.b", "pair.out -> sink.x"])
    summary = OfflineExecutor(net).run()
    assert sink.values() == [13.0, 24.0, 56.0] and sink.times() == [0, 0, 7]
    assert summary.total_lost == 0


# --- 13. what failed, interrupted, blocked and skipping runs report ------------------------------
def test_a_failed_run_reports_the_events_it_processed() -> None:
    boom, sink = Boom("boom", at=3.0), CollectingSink("sink")
    net = _net(Counter("src", n=6, period_ns=1_000), boom, sink, connections=["src.out -> boom.x", "boom.y -> sink.x"])
    with pytest.raises(ComponentError) as ei:
        OfflineExecutor(net).run()
    # 4 samples from the source, 4 delivered to boom, 3 passed on to sink (the 4th raised)
    assert ei.value.summary.events == 4 + 4 + 3
    assert "graph 'graph': 11 events" in ei.value.summary.format()


class FanThenStop(Component):
    """Emits to its output (3 consumers), then raises ``exc`` on the sample ``at``."""

    x = Input(float)
    y = Output(float)
    at = Param(float, default=2.0)
    interrupt = Param(bool, default=True)

    def process(self, t: int) -> None:
        v = self.x.take()
        self.y.emit(t, v)
        if v == self.at:
            raise KeyboardInterrupt if self.interrupt else ValueError("after emitting")


@pytest.mark.parametrize("interrupt", [True, False])
def test_samples_in_flight_when_a_run_ends_early_are_counted_as_lost(interrupt: bool) -> None:
    sinks = [CollectingSink(f"k{i}") for i in range(3)]
    fan = FanThenStop("fan", at=2.0, interrupt=interrupt)
    net = _net(Counter("src", n=5, period_ns=10), fan, *sinks,
               connections=["src.out -> fan.x"] + [f"fan.y -> k{i}.x" for i in range(3)])
    if interrupt:
        summary = OfflineExecutor(net).run()
        assert summary.interrupted
    else:
        with pytest.raises(ComponentError) as ei:
            OfflineExecutor(net).run()
        summary = ei.value.summary
    # samples 0 and 1 reached every sink; sample 2 was emitted to 3 inputs and never delivered
    assert [k.values() for k in sinks] == [[0.0, 1.0]] * 3
    assert {k: v["unconsumed"] for k, v in summary.drops().items()} == {f"k{i}.x": 1 for i in range(3)}
    assert summary.total_lost == 3


class AlwaysFails(Component):
    x = Input(float)

    def process(self, t: int) -> None:
        raise ValueError(f"cannot use {self.x.take()}")


@pytest.mark.parametrize("executor", [OfflineExecutor, RealTimeExecutor])
def test_on_error_skip_logs_the_first_skips_then_counts(executor, caplog: pytest.LogCaptureFixture) -> None:
    net = _net(Counter("src", n=20, period_ns=1_000), AlwaysFails("bad"), connections=["src.out -> bad.x"],
               on_error={"bad": "skip"})
    with caplog.at_level(logging.WARNING, logger="impala_flow"):
        summary = executor(net).run()
    lines = [r.getMessage() for r in caplog.records if r.name == "impala_flow.bad"]
    assert len(lines) == SKIP_LOG_LIMIT + 1
    assert lines[0].startswith("skipped t=") and "ValueError: cannot use 0.0" in lines[0]
    assert lines[-1] == "further skips are counted, not logged: the total is in the run summary"
    assert summary.skipped == {"bad": 20}
    assert summary.first_skip["bad"].endswith("ValueError: cannot use 0.0")
    assert "20 skipped after errors (first at t=" in summary.format()


class Huge(Source):
    out = Output(float)
    stamp = Param(int, default=1 << 63)  # not named *_ns: a *_ns parameter out of int64 is refused sooner

    def generate(self):
        yield 0, "out", 0.0
        yield self.stamp, "out", 1.0


@pytest.mark.parametrize("executor", [OfflineExecutor, RealTimeExecutor])
@pytest.mark.parametrize("t_ns", [1 << 63, -(1 << 63) - 1])
def test_timestamps_outside_int64_are_refused_at_the_source(executor, t_ns: int) -> None:
    net = _net(Huge("radar", stamp=t_ns), CollectingSink("sink"), connections=["radar.out -> sink.x"])
    with pytest.raises(ComponentError) as ei:
        executor(net).run()
    assert str(ei.value).startswith(f"component 'radar', in generate(): OverflowError: yielded t={t_ns} ns on "
                                    "'out', outside the int64 range")


def test_the_largest_int64_timestamp_is_accepted() -> None:
    sink = CollectingSink("sink")
    net = _net(Huge("radar", stamp=(1 << 63) - 1), sink, connections=["radar.out -> sink.x"])
    OfflineExecutor(net).run()
    assert sink.times() == [0, (1 << 63) - 1]


def test_block_policy_in_real_time_reports_backpressure() -> None:
    class Burst(Source):
        out = Output(float)

        def generate(self):
            for i in range(6):
                yield 0, "out", float(i)  # all at once: faster than the consumer

    class SlowSink(Component):
        x = Input(float, maxsize=1, overflow="block")

        def start(self) -> None:
            self.got: list[float] = []

        def process(self, t: int) -> None:
            time.sleep(0.02)
            self.got.append(self.x.take())

    slow = SlowSink("slow")
    net = _net(Burst("src"), slow, connections=["src.out -> slow.x"])
    summary = RealTimeExecutor(net).run()
    assert slow.got == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0] and summary.total_lost == 0  # block: nothing dropped
    bp = summary.backpressure()
    assert list(bp) == ["slow.x"] and bp["slow.x"]["blocked"] >= 1 and bp["slow.x"]["blocked_s"] > 0
    assert summary.inputs["slow.x"]["blocked_ns"] > 0
    lines = summary.format().splitlines()
    assert any(line.startswith("  BACKPRESSURE at slow.x: producers blocked ") for line in lines)


def test_thread_safety_of_the_stop_event_is_unchanged() -> None:
    """Interrupting through the stop event still ends cleanly and counts what was in flight."""
    stop = threading.Event()

    class Endless(Source):
        out = Output(float)

        def generate(self):
            i = 0
            while True:
                if i == 3000:
                    stop.set()
                yield i, "out", 0.0
                i += 1

    sink = CollectingSink("sink")
    net = _net(Endless("src"), sink, connections=["src.out -> sink.x"])
    summary = OfflineExecutor(net, stop_event=stop).run()
    assert summary.interrupted
    st = summary.inputs["sink.x"]
    assert st["received"] + st["unconsumed"] == summary.emitted["src.out"]  # every emitted sample accounted for
