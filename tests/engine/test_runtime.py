"""The real-time threaded executor (impala_flow._realtime) and clean stops on signals.

No assertion here depends on the machine's speed: timeouts only guard against hangs, and
drop counts are made deterministic by gating the consumers with events.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from impala_flow._clock import MissionClock
from impala_flow._component import Component, Input, Output, Param, Periodic, Source
from impala_flow._network import Network
from impala_flow._realtime import RealTimeExecutor
from impala_flow._session import Session
from impala_flow._summary import ComponentError, RunSummary
from impala_flow.testing import CollectingSink, ScriptedSource, connect, plugin_of

HANG_S = 60.0  # only to turn a hang into a failure


# --- components --------------------------------------------------------------------------
class LiveCounter(Source):
    """Live: ``n`` samples (values 0..n-1) every ``period_s``, stamped with ``now_ns()``."""

    live = True
    out = Output(object)
    n = Param(int, default=100, ge=0)
    period_s = Param(float, default=0.0005, ge=0)

    def generate(self):
        for i in range(self.n):
            if self.period_s:
                time.sleep(self.period_s)
            yield self.now_ns(), "out", i

    def stop(self) -> None:
        self.stops = getattr(self, "stops", 0) + 1


class Burst(Source):
    """Non-live: ``n`` samples 1 µs apart (released at once); sets ``sent`` after the last."""

    out = Output(object)
    n = Param(int, default=10, ge=0)
    clock_offset_ns = Param(int, default=0)

    def __init__(self, name: str, **kw: Any) -> None:
        super().__init__(name, **kw)
        self.sent = threading.Event()
        self.yielded_at: list[int] = []  # consumer progress when each sample was yielded
        self.consumer: Any = None

    def generate(self):
        for i in range(self.n):
            if self.consumer is not None:
                self.yielded_at.append(self.consumer.done)
            yield i * 1000, "out", i
        self.sent.set()


class Tracker:
    """Counts concurrent process calls, per component and overall."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.active: dict[str, int] = {}
        self.max_per: dict[str, int] = {}
        self.total = 0
        self.max_total = 0

    def enter(self, name: str) -> None:
        with self.lock:
            self.active[name] = self.active.get(name, 0) + 1
            self.max_per[name] = max(self.max_per.get(name, 0), self.active[name])
            self.total += 1
            self.max_total = max(self.max_total, self.total)

    def leave(self, name: str) -> None:
        with self.lock:
            self.active[name] -= 1
            self.total -= 1


class Work(Component):
    """Pass-through that holds the GIL-free section for a while (sleep + numpy)."""

    x = Input(object)
    y = Output(object)
    sleep_s = Param(float, default=0.0)

    tracker: Tracker | None = None

    def start(self) -> None:
        self.done = 0
        self.stops = 0

    def process(self, t: int) -> None:
        tr = self.tracker
        if tr is not None:
            tr.enter(self.name)
        try:
            s = self.x.take_sample()
            if self.sleep_s:
                time.sleep(self.sleep_s)
                np.linalg.svd(np.ones((32, 32)))
            self.y.emit(s.timestamp, s.data)
            self.done += 1
        finally:
            if tr is not None:
                tr.leave(self.name)

    def stop(self) -> None:
        self.stops += 1


class Gated(Component):
    """Waits for ``gate`` before taking each sample (makes overflow counts exact)."""

    x = Input(object, maxsize=3, overflow="drop_newest")
    y = Output(object)
    overflow = Param(str, default="drop_newest", choices=("block", "drop_oldest", "drop_newest"))
    maxsize = Param(int, default=3, ge=1)
    sleep_s = Param(float, default=0.0)

    gate: threading.Event | None = None

    @classmethod
    def declare_ports(cls, params: dict[str, Any]) -> tuple[dict[str, Input], dict[str, Output]]:
        return ({"x": Input(object, maxsize=params["maxsize"], overflow=params["overflow"])},
                {"y": Output(object)})

    def start(self) -> None:
        self.done = 0
        self.values: list[Any] = []

    def process(self, t: int) -> None:
        if self.gate is not None:
            assert self.gate.wait(HANG_S)
        if self.sleep_s:
            time.sleep(self.sleep_s)
        v = self.x.take()
        self.values.append(v)
        self.done += 1
        self.y.emit(t, v)


class Boom(Component):
    x = Input(object)
    y = Output(object)
    at = Param(int, default=3)

    def start(self) -> None:
        self.stops = 0

    def process(self, t: int) -> None:
        v = self.x.take()
        if v == self.at:
            raise ValueError(f"bad value {v}")
        self.y.emit(t, v)

    def stop(self) -> None:
        self.stops += 1


class StopCountingSink(CollectingSink):
    def start(self) -> None:
        super().start()
        self.stops = 0

    def stop(self) -> None:
        self.stops += 1


class Ticker(Component):
    """Periodic timer only."""

    tick = Periodic(0.01)
    x = Input(object, required=False)

    def start(self) -> None:
        self.ticks: list[int] = []
        self.triggers: set[str] = set()

    def process(self, t: int) -> None:
        self.triggers.add(self.trigger)
        if self.trigger == "tick":
            self.ticks.append(t)
        else:
            self.x.take()


class Pair(Component):
    a = Input(object, sync="ab", tolerance=0.0)
    b = Input(object, sync="ab", tolerance=0.0)

    def start(self) -> None:
        self.pairs: list[tuple[Any, Any, int]] = []

    def process(self, t: int) -> None:
        self.pairs.append((self.a.take(), self.b.take(), t))


# --- helpers -----------------------------------------------------------------------------
def make_net(*comps: Component, connections: list[str] = (), on_error: dict[str, str] | None = None) -> Network:
    net = Network(name="rt-test")
    for c in comps:
        net.add(c, on_error=(on_error or {}).get(c.name, "stop"))
    for spec in connections:
        connect(net, spec)
    return net


def run_rt(net: Network, **kw: Any) -> RunSummary:
    """Run on the real-time executor in a thread, failing (not hanging) after HANG_S."""
    box: dict[str, Any] = {}
    ex = RealTimeExecutor(net, **kw)

    def target() -> None:
        try:
            box["summary"] = ex.run()
        except BaseException as e:  # re-raised in the test's thread
            box["error"] = e

    th = threading.Thread(target=target, daemon=True)
    th.start()
    th.join(HANG_S)
    if th.is_alive():
        ex.stop_event.set()
        th.join(10)
        pytest.fail(f"real-time run did not end within {HANG_S} s")
    if "error" in box:
        raise box["error"]
    return box["summary"]


# --- delivery, order, clock, concurrency -------------------------------------------------
def test_live_source_every_sample_once_in_order_on_the_mission_clock() -> None:
    n = 300
    clock = MissionClock()
    src, mid, sink = LiveCounter("src", n=n, period_s=0.0002), Work("mid"), StopCountingSink("sink")
    net = make_net(src, mid, sink, connections=["src.out -> mid.x", "mid.y -> sink.x"])
    summary = run_rt(net, clock=clock)
    assert sink.values() == list(range(n))
    times = sink.times()
    assert all(b > a for a, b in zip(times, times[1:], strict=False))
    assert summary.mission_start_ns <= times[0] and times[-1] <= summary.mission_end_ns
    assert src.now_ns() - clock.now_ns() <= 0  # the shared clock was handed to every component
    assert summary.processed == {"src": 0, "mid": n, "sink": n}
    assert summary.emitted["src.out"] == n and summary.emitted["mid.y"] == n
    assert summary.drops() == {} and not summary.interrupted and summary.error is None
    assert src.stops == mid.stops == sink.stops == 1


def test_one_process_at_a_time_per_component_but_components_overlap() -> None:
    tracker = Tracker()
    src = Burst("src", n=40)
    a, b = Work("a", sleep_s=0.002), Work("b", sleep_s=0.002)
    a.tracker = b.tracker = tracker
    sa, sb = CollectingSink("sa"), CollectingSink("sb")
    net = make_net(src, a, b, sa, sb, connections=[
        "src.out -> a.x", "src.out -> b.x", "a.y -> sa.x", "b.y -> sb.x"])
    run_rt(net)
    assert tracker.max_per == {"a": 1, "b": 1}
    assert tracker.max_total >= 2  # a and b ran at the same time at least once
    assert sa.values() == sb.values() == list(range(40))


def test_two_live_sources_share_one_time_base_and_fan_in_keeps_per_connection_order() -> None:
    s1, s2 = LiveCounter("s1", n=200, period_s=0.0002), LiveCounter("s2", n=200, period_s=0.0003)
    sink = CollectingSink("sink", ports=["a", "b"])
    summary = run_rt(make_net(s1, s2, sink, connections=["s1.out -> sink.a", "s2.out -> sink.b"]))
    for port in ("a", "b"):
        assert sink.values(port) == list(range(200))
        ts = sink.times(port)
        assert all(y > x for x, y in zip(ts, ts[1:], strict=False))
        assert summary.mission_start_ns <= ts[0] and ts[-1] <= summary.mission_end_ns


def test_non_live_source_is_paced_and_restamped_on_mission_time() -> None:
    period = 2_000_000  # 2 ms of mission time
    src = ScriptedSource("src", samples=[(10**12 + i * period, "out", i) for i in range(20)])
    sink = CollectingSink("sink")
    summary = run_rt(make_net(src, sink, connections=["src.out -> sink.x"]))
    ts = sink.times()
    assert sink.values() == list(range(20))
    assert [t - ts[0] for t in ts] == [i * period for i in range(20)]  # spacing kept exactly
    assert summary.mission_start_ns <= ts[0] <= ts[-1] <= summary.mission_end_ns
    assert summary.mission_end_ns - summary.mission_start_ns >= 19 * period  # released on time, not at once


def test_clock_offset_is_applied_on_the_way_in_and_reported() -> None:
    src = Burst("gps", n=5, clock_offset_ns=-250_000_000)
    sink = CollectingSink("sink")
    net = make_net(src, sink, connections=["gps.out -> sink.x"])
    summary = run_rt(net)
    start = summary.mission_start_ns
    assert sink.times() == [start - 250_000_000 + i * 1000 for i in range(5)]
    assert summary.extra["gps"]["clock_offset_ns"] == -250_000_000
    assert net.metadata["clock_offsets_ns"] == {"gps": -250_000_000}


def test_sync_group_in_real_time() -> None:
    a = ScriptedSource("sa", samples=[(i * 1_000_000, "out", f"a{i}") for i in range(30)])
    b = ScriptedSource("sb", samples=[(i * 1_000_000, "out", f"b{i}") for i in range(30)])
    pair = Pair("pair")
    summary = run_rt(make_net(a, b, pair, connections=["sa.out -> pair.a", "sb.out -> pair.b"]))
    assert [(x, y) for x, y, _ in pair.pairs] == [(f"a{i}", f"b{i}") for i in range(30)]
    assert summary.drops() == {}


def test_periodic_timer_fires_on_mission_time() -> None:
    src = LiveCounter("src", n=60, period_s=0.005)
    tick = Ticker("tick")
    summary = run_rt(make_net(src, tick, connections=["src.out -> tick.x"]))
    p = 10_000_000
    assert len(tick.ticks) >= 3
    assert all(t % p == 0 for t in tick.ticks)
    assert all(b > a for a, b in zip(tick.ticks, tick.ticks[1:], strict=False))
    assert summary.mission_start_ns <= tick.ticks[0] and tick.ticks[-1] <= summary.mission_end_ns
    assert tick.triggers == {"tick", "x"}


# --- overflow policies -------------------------------------------------------------------
def test_block_makes_the_fast_producer_wait_and_loses_nothing() -> None:
    n = 60
    src = Burst("src", n=n)
    slow = Gated("slow", overflow="block", maxsize=2, sleep_s=0.001)
    src.consumer = slow
    sink = CollectingSink("sink")
    summary = run_rt(make_net(src, slow, sink, connections=["src.out -> slow.x", "slow.y -> sink.x"]))
    assert sink.values() == list(range(n))
    assert summary.drops() == {}
    st = summary.inputs["slow.x"]
    assert st["received"] == n and st["dropped"] == 0 and st["high_water"] == 2
    # the producer could never be more than 2 queued + 1 in process + the one being pushed ahead
    assert all(done >= k - 4 for k, done in enumerate(src.yielded_at))


@pytest.mark.parametrize(("overflow", "kept"), [("drop_newest", [0, 1, 2]), ("drop_oldest", [7, 8, 9])])
def test_drop_policies_count_exactly(overflow: str, kept: list[int]) -> None:
    src = Burst("src", n=10)
    gated = Gated("gated", overflow=overflow, maxsize=3)
    gated.gate = src.sent  # the consumer takes nothing before the producer has pushed all 10
    sink = CollectingSink("sink")
    summary = run_rt(make_net(src, gated, sink, connections=["src.out -> gated.x", "gated.y -> sink.x"]))
    assert gated.values == kept
    assert sink.values() == kept
    assert summary.inputs["gated.x"]["dropped"] == 7
    assert summary.inputs["gated.x"]["received"] == 10
    assert summary.drops() == {"gated.x": {"dropped": 7}}
    assert summary.processed["gated"] == 3


# --- errors ------------------------------------------------------------------------------
def test_component_error_names_component_input_and_time_and_everyone_stops() -> None:
    src = Burst("src", n=10)
    boom = Boom("boom", at=3)
    other = Work("other")
    s1, s2 = StopCountingSink("s1"), StopCountingSink("s2")
    net = make_net(src, boom, other, s1, s2, connections=[
        "src.out -> boom.x", "src.out -> other.x", "boom.y -> s1.x", "other.y -> s2.x"])
    with pytest.raises(ComponentError) as ei:
        run_rt(net)
    err = ei.value
    summary = err.summary  # type: ignore[attr-defined]
    t_bad = summary.mission_start_ns + 3 * 1000
    assert (err.component, err.trigger, err.t_ns, err.phase) == ("boom", "x", t_bad, "process")
    assert f"component 'boom', input 'x', sample t={t_bad} ns: ValueError: bad value 3" in str(err)
    assert summary.error == str(err)
    assert boom.stops == other.stops == s1.stops == s2.stops == 1
    # after an error nothing new starts: what boom sent before failing was processed or is reported
    got = s1.values()
    assert got == [0, 1, 2][:len(got)]
    st = summary.inputs["s1.x"]
    assert st["received"] == 3 and st["unconsumed"] == 3 - len(got)


def test_on_error_skip_counts_skips_and_continues() -> None:
    src = Burst("src", n=10)
    boom, sink = Boom("boom", at=3), CollectingSink("sink")
    net = make_net(src, boom, sink, connections=["src.out -> boom.x", "boom.y -> sink.x"], on_error={"boom": "skip"})
    summary = run_rt(net)
    assert sink.values() == [0, 1, 2, 4, 5, 6, 7, 8, 9]
    assert summary.skipped == {"boom": 1}
    assert summary.processed["boom"] == 9
    assert summary.error is None


def test_source_error_is_reported_with_its_name() -> None:
    class Broken(Source):
        out = Output(object)

        def generate(self):
            yield 0, "out", 1
            raise OSError("device unplugged")

    sink = StopCountingSink("sink")
    with pytest.raises(ComponentError, match="component 'dev', in generate\\(\\): OSError: device unplugged"):
        run_rt(make_net(Broken("dev"), sink, connections=["dev.out -> sink.x"]))
    assert sink.stops == 1


def test_start_error_stops_the_started_components() -> None:
    class BadStart(Component):
        x = Input(object)

        def start(self) -> None:
            raise RuntimeError("no device")

    src = LiveCounter("src", n=5)
    with pytest.raises(ComponentError, match="component 'bad', in start\\(\\): RuntimeError: no device"):
        run_rt(make_net(src, BadStart("bad"), connections=["src.out -> bad.x"]))
    assert src.stops == 1


# --- clean stop ---------------------------------------------------------------------------
def test_stop_event_stops_cleanly_and_drains_what_was_acquired() -> None:
    src = LiveCounter("src", n=10**9, period_s=0.001)
    mid, sink = Work("mid", sleep_s=0.0005), StopCountingSink("sink")
    net = make_net(src, mid, sink, connections=["src.out -> mid.x", "mid.y -> sink.x"])
    stop = threading.Event()
    threading.Timer(0.3, stop.set).start()
    summary = run_rt(net, stop_event=stop)
    assert summary.interrupted and summary.error is None
    assert src.stops == mid.stops == sink.stops == 1
    n = summary.emitted["src.out"]
    assert n > 0 and sink.values() == list(range(n))  # everything acquired was processed
    assert summary.drops() == {}


def test_stop_releases_a_producer_blocked_on_a_stuck_consumer() -> None:
    gate = threading.Event()
    src = Burst("src", n=50)
    stuck = Gated("stuck", overflow="block", maxsize=2)
    stuck.gate = gate  # never opened before the stop
    stop = threading.Event()
    threading.Timer(0.3, stop.set).start()
    threading.Timer(0.3 + 1.0, gate.set).start()  # after the drain deadline: the call in flight ends
    summary = run_rt(make_net(src, stuck, connections=["src.out -> stuck.x"]), stop_event=stop,
                     drain_timeout_s=0.5)
    assert summary.interrupted
    st = summary.inputs["stuck.x"]
    assert st["dropped"] == 0 and st["received"] == summary.emitted["src.out"]
    assert st["received"] == summary.processed["stuck"] + st["unconsumed"]  # nothing lost silently


def test_timer_only_graph_runs_until_stopped() -> None:
    tick = Ticker("tick")
    stop = threading.Event()
    threading.Timer(0.15, stop.set).start()
    summary = run_rt(make_net(tick), stop_event=stop)
    assert summary.interrupted and len(tick.ticks) >= 2
    assert all(t % 10_000_000 == 0 for t in tick.ticks)


def test_a_source_stuck_in_generate_is_abandoned_after_the_timeout() -> None:
    release = threading.Event()

    class Stuck(Source):
        live = True
        out = Output(object)

        def generate(self):
            yield self.now_ns(), "out", 1
            release.wait(HANG_S)  # a driver call that never returns
            yield self.now_ns(), "out", 2

    sink = StopCountingSink("sink")
    stop = threading.Event()
    threading.Timer(0.1, stop.set).start()
    try:
        summary = run_rt(make_net(Stuck("dev"), sink, connections=["dev.out -> sink.x"]), stop_event=stop,
                         stop_timeout_s=0.3)
    finally:
        release.set()
    assert summary.interrupted and sink.values() == [1] and sink.stops == 1


def test_session_runs_a_realtime_yaml_graph() -> None:
    session = Session(extra_plugins={"t": plugin_of(LiveCounter, Work, CollectingSink)}, entrypoints=False)
    spec = session.load_text(textwrap.dedent("""
        name: live
        clock: {mode: realtime}
        components:
          src: {type: t.LiveCounter, params: {n: 50}}
          mid: {type: t.Work}
          sink: {type: t.CollectingSink}
        connections:
          - src.out -> mid.x
          - mid.y -> sink.x
    """))
    box: dict[str, Any] = {}
    th = threading.Thread(target=lambda: box.setdefault("s", session.run(spec)), daemon=True)
    th.start()
    th.join(HANG_S)
    assert not th.is_alive()
    summary = box["s"]
    assert summary.processed["sink"] == 50 and summary.drops() == {}


# --- signals in a real subprocess ---------------------------------------------------------
SCRIPT = r'''
import sys, time
from pathlib import Path
from impala_flow._component import Component, Input, Output, Param, Source
from impala_flow._session import Session
from impala_flow.testing import plugin_of
import impala_flow.cli
import impala_flow.cli._run

OUT = Path(sys.argv[1])


class Marked:
    def stop(self):
        with open(OUT / f"{self.name}.stop", "a") as f:
            f.write("stop\n")


class Feed(Marked, Source):
    live = __LIVE__
    out = Output(object)

    def generate(self):
        i = 0
        while True:
            if i == 20:
                (OUT / "running").write_text("yes")
            t = self.now_ns() if self.live else i * 1_000_000
            if self.live:
                time.sleep(0.001)
            yield t, "out", i
            i += 1


class Mid(Marked, Component):
    x = Input(object)
    y = Output(object)

    def process(self, t):
        self.y.emit(t, self.x.take())


class Writer(Marked, Component):
    x = Input(object)

    def start(self):
        self.f = open(OUT / "rows.txt", "w")

    def process(self, t):
        self.f.write(f"{t},{self.x.take()}\n")

    def stop(self):
        self.f.close()
        super().stop()


impala_flow.cli._run.open_session = lambda: Session(
    extra_plugins={"t": plugin_of(Feed, Mid, Writer)}, entrypoints=False)
sys.exit(impala_flow.cli.main(["run", sys.argv[2], "--no-progress"]))
'''

GRAPH = """
name: signal-test
clock: {clock}
components:
  feed: {{type: t.Feed}}
  mid: {{type: t.Mid}}
  writer: {{type: t.Writer}}
connections:
  - feed.out -> mid.x
  - mid.y -> writer.x
"""


def _run_and_signal(tmp_path: Path, sig: int, live: bool) -> tuple[int, str]:
    script = tmp_path / "run_graph.py"
    script.write_text(SCRIPT.replace("__LIVE__", str(live)))
    graph = tmp_path / "graph.yaml"
    graph.write_text(GRAPH.format(clock="{mode: realtime}" if live else "{mode: replay, speed: 1.0}"))
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, str(script), str(tmp_path), str(graph)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + HANG_S
        while not (tmp_path / "running").exists():
            if proc.poll() is not None or time.monotonic() > deadline:
                out, err = proc.communicate(timeout=10)
                pytest.fail(f"graph did not start (rc={proc.returncode}):\n{out}\n{err}")
            time.sleep(0.02)
        time.sleep(0.2)
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=20)  # clean exit within a few seconds
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    return proc.returncode, err


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
@pytest.mark.parametrize("live", [True, False], ids=["realtime", "offline"])
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_signal_stops_a_running_graph_cleanly(tmp_path: Path, sig: int, live: bool) -> None:
    rc, err = _run_and_signal(tmp_path, sig, live)
    assert rc == 130, err
    for name in ("feed", "mid", "writer"):
        assert (tmp_path / f"{name}.stop").read_text() == "stop\n", name  # stop() ran exactly once
    assert "graph 'signal-test'" in err and "INTERRUPTED" in err  # the summary was printed
    assert "Traceback" not in err
    rows = (tmp_path / "rows.txt").read_text()
    assert rows.endswith("\n")  # nothing half-written
    values = [int(line.split(",")[1]) for line in rows.splitlines()]
    assert values == list(range(len(values))) and len(values) >= 20


def test_cli_realtime_run_of_the_example_plugin_stops_on_sigterm(tmp_path: Path, example_plugin: Any) -> None:
    csv = tmp_path / "out.csv"
    graph = tmp_path / "g.yaml"
    graph.write_text(textwrap.dedent(f"""
        name: example-live
        clock: {{mode: realtime}}
        components:
          count: {{type: example.Counter, params: {{rate: 200.0, count: 1000000}}}}
          avg: {{type: example.MovingAverage}}
          csv: {{type: example.CsvWriter, params: {{path: "{csv}"}}}}
        connections:
          - count.value -> avg.x
          - avg.mean -> csv.x
    """))
    proc = subprocess.Popen([sys.executable, "-c", "import sys, impala_flow.cli; sys.exit(impala_flow.cli.main())",
                             "run", str(graph), "--no-progress"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        deadline = time.monotonic() + HANG_S
        while not (csv.exists() and csv.read_text().count("\n") > 5):
            if proc.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f"graph did not start: {proc.communicate(timeout=10)}")
            time.sleep(0.05)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130, err
    assert "INTERRUPTED" in err
    text = csv.read_text()
    assert text.startswith("t_ns,value\n") and text.endswith("\n")


class Summing(Component):
    x = Input(object)
    total = Output(float)

    def start(self) -> None:
        self.sum, self.flushes = 0.0, 0

    def process(self, t: int) -> None:
        self.sum += float(self.x.take())

    def flush(self, t: int) -> None:
        self.flushes += 1
        self.total.emit(t, self.sum)


def test_flush_at_the_end_of_a_live_run_emits_and_is_drained_before_stop() -> None:
    n = 50
    src, acc, sink = LiveCounter("src", n=n, period_s=0.0002), Summing("acc"), StopCountingSink("sink")
    net = make_net(src, acc, sink, connections=["src.out -> acc.x", "acc.total -> sink.x"])
    summary = run_rt(net)
    assert acc.flushes == 1 and sink.values() == [float(sum(range(n)))]
    assert sink.stops == 1 and summary.drops() == {}
