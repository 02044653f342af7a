"""What a run reports beyond its counts, and how it ends early: ``duration`` (both executors),
the time per ``process`` call (both), the latency per output (real time), a bounded slow stage
that drops whole samples (real time).

Durations are checked against known truths without measuring the machine: the time per call
against a fake ``perf_counter_ns`` that the components themselves advance, the latency against a
fake mission clock advanced the same way (one sample in the chain at a time), the histogram
against numpy's quantiles."""

from __future__ import annotations

import textwrap
import threading
import time
from typing import Any

import numpy as np
import pytest

from impala_flow import Component, Input, Output, Param, Session, Source
from impala_flow._network import Network
from impala_flow._offline import OfflineExecutor
from impala_flow._realtime import RealTimeExecutor
from impala_flow._summary import RunSummary
from impala_flow._timing import Histogram
from impala_flow.testing import CollectingSink, connect, plugin_of

HANG_S = 60.0  # only to turn a hang into a failure


# --- components --------------------------------------------------------------------------
class Ticks(Source):
    """``n`` samples (values 0..n-1) every ``period_ns`` from t=``t0_ns``; notes when it is closed."""

    out = Output(float)
    n = Param(int, default=100, ge=0)
    period_ns = Param(int, default=10_000_000, ge=1)
    t0_ns = Param(int, default=1_000_000_000)

    def start(self) -> None:
        self.closed = False

    def generate(self):
        try:
            for i in range(self.n):
                yield self.t0_ns + i * self.period_ns, "out", float(i)
        finally:
            self.closed = True


class LiveTicks(Source):
    """Live: a sample every ``period_s`` until stopped."""

    live = True
    out = Output(float)
    period_s = Param(float, default=0.002, gt=0)

    def generate(self):
        i = 0
        while True:
            time.sleep(self.period_s)
            yield self.now_ns(), "out", float(i)
            i += 1


class Summing(Component):
    """Emits the running sum at flush only."""

    x = Input(float)
    total = Output(float)

    def start(self) -> None:
        self.sum, self.flushes = 0.0, 0

    def process(self, t: int) -> None:
        self.sum += self.x.take()

    def flush(self, t: int) -> None:
        self.flushes += 1
        self.total.emit(t, self.sum)


class FakeCounter:
    """A fake ``time.perf_counter_ns`` / mission clock: advanced only by :meth:`advance`."""

    def __init__(self, t0: int = 10**12) -> None:
        self.t = t0

    def __call__(self) -> int:
        return self.t

    def now_ns(self) -> int:
        return self.t

    def advance(self, dt: int) -> None:
        self.t += dt


class Costly(Component):
    """Pass-through whose ``process`` "takes" ``cost_ns(i)`` on the fake counter: (i % 10 + 1) ms."""

    x = Input(float)
    y = Output(float)
    counter: FakeCounter | None = None

    def process(self, t: int) -> None:
        v = self.x.take()
        self.counter.advance((int(v) % 10 + 1) * 1_000_000)  # type: ignore[union-attr]
        self.y.emit(t, v)


def make_net(*comps: Component, connections: list[str]) -> Network:
    net = Network(name="figures")
    for c in comps:
        net.add(c)
    for spec in connections:
        connect(net, spec)
    return net


def run_thread(fn: Any) -> RunSummary:
    box: dict[str, Any] = {}

    def target() -> None:
        try:
            box["s"] = fn()
        except BaseException as e:  # re-raised in the test's thread
            box["e"] = e

    th = threading.Thread(target=target, daemon=True)
    th.start()
    th.join(HANG_S)
    assert not th.is_alive(), f"the run did not end within {HANG_S} s"
    if "e" in box:
        raise box["e"]
    return box["s"]


# --- duration ----------------------------------------------------------------------------
def test_offline_duration_takes_the_samples_before_it_then_flushes() -> None:
    src, acc, sink = Ticks("src", n=100), Summing("acc"), CollectingSink("sink")
    net = make_net(src, acc, sink, connections=["src.out -> acc.x", "acc.total -> sink.x"])
    summary = OfflineExecutor(net, duration_ns=250_000_000).run()
    # 10 ms apart from t0: the samples before t0 + 0.25 s are 0..24 (half-open window)
    assert summary.processed["acc"] == 25 and sink.values() == [float(sum(range(25)))]
    assert acc.flushes == 1 and src.closed
    assert summary.stopped_at_duration and not summary.interrupted and summary.duration_s == 0.25
    assert summary.mission_start_ns == 1_000_000_000 and summary.mission_end_ns == 1_240_000_000
    assert summary.drops() == {} and summary.total_lost == 0
    assert "stopped at --duration 0.25 s" in summary.format().splitlines()[0]


def test_offline_duration_equals_inputs_ending_there() -> None:
    """Deterministic: a run stopped at its duration is the run whose source ended there."""
    def values(n: int, duration_ns: int | None) -> list[Any]:
        src, acc, sink = Ticks("src", n=n), Summing("acc"), CollectingSink("sink")
        net = make_net(src, acc, sink, connections=["src.out -> acc.x", "acc.total -> sink.x"])
        OfflineExecutor(net, duration_ns=duration_ns).run()
        return [(s.timestamp, s.data) for s in sink.samples]

    assert values(1000, 333_000_000) == values(34, None)


def test_a_duration_past_the_inputs_changes_nothing() -> None:
    src, sink = Ticks("src", n=10), CollectingSink("sink")
    summary = OfflineExecutor(make_net(src, sink, connections=["src.out -> sink.x"]), duration_ns=10**12).run()
    assert summary.processed["sink"] == 10 and not summary.stopped_at_duration
    assert "--duration" not in summary.format()


def test_realtime_duration_stops_a_live_run_cleanly_and_flushes() -> None:
    src, acc, sink = LiveTicks("src"), Summing("acc"), CollectingSink("sink")
    net = make_net(src, acc, sink, connections=["src.out -> acc.x", "acc.total -> sink.x"])
    summary = run_thread(lambda: RealTimeExecutor(net, duration_ns=300_000_000).run())
    n = summary.emitted["src.out"]
    assert summary.stopped_at_duration and not summary.interrupted and summary.error is None
    assert n > 0 and summary.processed["acc"] == n                  # everything acquired was processed
    assert acc.flushes == 1 and sink.values() == [float(sum(range(n)))]
    assert summary.mission_end_ns - summary.mission_start_ns >= 300_000_000   # never before its duration
    assert summary.drops() == {}


class SilentDevice(Source):
    """Live: one sample, then a device that says nothing more: it waits until asked to stop."""

    live = True
    out = Output(float)

    def start(self) -> None:
        self.wake = threading.Event()
        self.asked = 0
        self.left = False

    def request_stop(self) -> None:
        self.asked += 1
        self.wake.set()

    def generate(self):
        try:
            yield self.now_ns(), "out", 0.0
            self.wake.wait(HANG_S)
        finally:
            self.left = True


def test_a_live_source_waiting_on_a_silent_device_is_asked_to_stop(caplog: pytest.LogCaptureFixture) -> None:
    """A source blocked in ``generate()`` (no ``yield`` to close it at) leaves when the executor
    asks (``request_stop``), long before ``stop_timeout_s``: not abandoned, nothing warned."""
    src, sink = SilentDevice("src"), CollectingSink("sink")
    net = make_net(src, sink, connections=["src.out -> sink.x"])
    summary = run_thread(lambda: RealTimeExecutor(net, duration_ns=100_000_000, stop_timeout_s=HANG_S).run())
    assert summary.stopped_at_duration and summary.error is None
    assert src.asked == 1 and src.left and sink.values() == [0.0]
    assert not [r for r in caplog.records if "abandoned" in r.getMessage()]


def test_session_duration_and_bad_values() -> None:
    session = Session(extra_plugins={"t": plugin_of(Ticks, CollectingSink)}, entrypoints=False)
    spec = session.load_text(textwrap.dedent("""
        name: d
        components:
          src: {type: t.Ticks, params: {n: 100}}
          sink: {type: t.CollectingSink}
        connections:
          - src.out -> sink.x
    """))
    summary = session.run(spec, duration_s=0.1)
    assert summary.processed["sink"] == 10 and summary.stopped_at_duration
    with pytest.raises(ValueError, match="duration_ns must be > 0"):
        OfflineExecutor(Network(), duration_ns=0)
    with pytest.raises(ValueError, match="duration_ns must be > 0"):
        RealTimeExecutor(Network(), duration_ns=-5)


# --- time per process call ---------------------------------------------------------------
def _costs_ns(n: int) -> np.ndarray:
    return (np.arange(n) % 10 + 1) * 1_000_000


@pytest.mark.parametrize("executor", ["offline", "realtime"])
def test_time_per_call_against_a_fake_perf_counter(executor: str, monkeypatch: pytest.MonkeyPatch) -> None:
    n = 200
    fake = FakeCounter()
    Costly.counter = fake
    monkeypatch.setattr(time, "perf_counter_ns", fake)
    src, work, sink = Ticks("src", n=n, period_ns=1000), Costly("work"), CollectingSink("sink")
    net = make_net(src, work, sink, connections=["src.out -> work.x", "work.y -> sink.x"])
    if executor == "offline":
        summary = OfflineExecutor(net).run()
    else:
        summary = run_thread(lambda: RealTimeExecutor(net).run())
    costs = _costs_ns(n)
    tm = summary.timing["work"]
    assert tm["calls"] == n
    assert tm["total_s"] == pytest.approx(costs.sum() / 1e9)
    assert tm["max_ms"] == pytest.approx(10.0)
    assert tm["median_ms"] == pytest.approx(np.quantile(costs, 0.5, method="lower") / 1e6, rel=0.016)
    assert tm["p99_ms"] == pytest.approx(np.quantile(costs, 0.99, method="lower") / 1e6, rel=0.016)
    assert tm["share"] == pytest.approx(tm["total_s"] / summary.wall_s, rel=1e-3, abs=1e-4)
    if executor == "offline":   # one thread: the sink's calls took no fake time
        assert summary.timing["sink"]["calls"] == n and summary.timing["sink"]["total_s"] == 0
    line = next(x for x in summary.format().splitlines() if x.startswith("  work: "))
    assert line.startswith(f"  work: {n} process calls, ") and "median" in line and "p99 per call" in line


def test_histogram_quantiles_against_numpy() -> None:
    rng = np.random.default_rng(0)
    values = np.concatenate([rng.lognormal(13, 2, 20_000), rng.integers(0, 128, 500)]).astype(np.int64)
    h = Histogram()
    for v in values:
        h.add(int(v))
    assert h.n == values.size and h.total == values.sum() and h.max == values.max()
    for q in (0.0, 0.01, 0.5, 0.9, 0.99, 1.0):
        want = np.quantile(values, q, method="lower")
        assert h.quantile(q) == pytest.approx(want, rel=1 / 64, abs=0.5)
    assert len(h.counts) < 1500          # bounded: 64 buckets per power of two that occurs
    small = Histogram()
    for v in (5, 5, 7, 100):
        small.add(v)
    assert small.quantile(0.5) == 5 and small.quantile(1.0) == 100   # exact below 128 ns


# --- latency -----------------------------------------------------------------------------
class Beams(Source):
    """Live: ``n`` beams, 1 ms apart on the fake mission clock; the next one only once the
    chain has finished with the previous one (``ready``), so the clock is advanced by one
    component at a time."""

    live = True
    out = Output(float)
    n = Param(int, default=40)
    clock: FakeCounter | None = None
    ready: threading.Event | None = None

    def generate(self):
        for i in range(self.n):
            if i:
                assert self.ready.wait(HANG_S)  # type: ignore[union-attr]
                self.ready.clear()  # type: ignore[union-attr]
            self.clock.advance(1_000_000)  # type: ignore[union-attr]
            yield self.now_ns(), "out", float(i)


class Front(Component):
    """Per beam: (i % 5 + 1) x 100 us of work on the fake clock."""

    x = Input(float)
    y = Output(float)
    clock: FakeCounter | None = None

    def process(self, t: int) -> None:
        v = self.x.take()
        self.clock.advance((int(v) % 5 + 1) * 100_000)  # type: ignore[union-attr]
        self.y.emit(t, v)


class Turns(Component):
    """Emits a turn (4 beams) when its last beam arrives, at no cost; otherwise lets the next beam come."""

    x = Input(float)
    turn = Output(object)
    ready: threading.Event | None = None

    def start(self) -> None:
        self.beams: list[float] = []

    def process(self, t: int) -> None:
        self.beams.append(self.x.take())
        if len(self.beams) == 4:
            self.turn.emit(t, tuple(self.beams))
            self.beams = []
        else:
            self.ready.set()  # type: ignore[union-attr]


class Poser(Component):
    """Per turn: 2 ms of work on the fake clock, then the pose."""

    turn = Input(object)
    pose = Output(object)
    clock: FakeCounter | None = None
    ready: threading.Event | None = None

    def process(self, t: int) -> None:
        turn = self.turn.take()
        self.clock.advance(2_000_000)  # type: ignore[union-attr]
        self.pose.emit(t, turn)
        self.ready.set()  # type: ignore[union-attr]


def run_turn_chain(turns: Component, n: int) -> RunSummary:
    """``n`` beams -> Front -> ``turns`` -> Poser -> a sink, live on one fake clock."""
    clock, ready = FakeCounter(), threading.Event()
    Beams.clock = Front.clock = Poser.clock = clock
    Beams.ready = type(turns).ready = Poser.ready = ready  # type: ignore[attr-defined]
    net = make_net(Beams("src", n=n), Front("front"), turns, Poser("poser"), CollectingSink("sink"), connections=[
        "src.out -> front.x", "front.y -> turns.x", "turns.turn -> poser.turn", "poser.pose -> sink.x"])
    return run_thread(lambda: RealTimeExecutor(net, clock=clock).run())


def test_latency_from_the_completing_beam_to_the_pose() -> None:
    n = 40
    summary = run_turn_chain(Turns("turns"), n)
    assert summary.processed["sink"] == n // 4
    work = (np.arange(n) % 5 + 1) * 100_000                      # Front's cost per beam
    last = work[3::4]                                             # the beam that completes each turn
    expected = {"front.y": work, "turns.turn": last, "poser.pose": last + 2_000_000}
    assert set(summary.latency) == set(expected)                  # sources' samples have no latency
    for key, ns in expected.items():
        lat = summary.latency[key]
        assert lat["count"] == ns.size
        assert lat["max_ms"] == pytest.approx(ns.max() / 1e6)
        assert lat["median_ms"] == pytest.approx(np.quantile(ns, 0.5, method="lower") / 1e6, rel=0.016)
        assert lat["p99_ms"] == pytest.approx(np.quantile(ns, 0.99, method="lower") / 1e6, rel=0.016)
    lines = summary.format().splitlines()
    assert any(x.startswith("  LATENCY poser.pose: ") and "over 10 samples" in x for x in lines)


class HeldTurns(Component):
    """Like :class:`Turns`, but holds each turn until the first beam of the next one (a component
    waiting for a feedback), then emits it with the origin of the beam that completed it
    (``work_origin_ns``): its latency counts the wait."""

    x = Input(float)
    turn = Output(object)
    ready: threading.Event | None = None

    def start(self) -> None:
        self.beams: list[float] = []
        self.held: tuple[tuple[float, ...], int | None] | None = None
        self.origins_offline: list[int | None] = []

    def process(self, t: int) -> None:
        self.beams.append(self.x.take())
        self.origins_offline.append(self.work_origin_ns)
        if self.held is not None:
            turn, origin = self.held
            self.held, now = None, self.work_origin_ns
            self.work_origin_ns = origin
            self.turn.emit(t, turn)
            self.work_origin_ns = now
        elif self.ready is not None:
            self.ready.set()
        if len(self.beams) == 4:
            self.held, self.beams = (tuple(self.beams), self.work_origin_ns), []


def test_a_held_result_counts_its_wait_in_its_latency() -> None:
    """Turn k completes at beam 4k+3 and leaves at beam 4k+4: its latency is Front's work on the
    completing beam, the 1 ms to the next beam and Front's work on that one (the fake clock's
    advances); the turn after it is still held at the end (not emitted)."""
    n = 40
    summary = run_turn_chain(HeldTurns("turns"), n)
    assert summary.processed["sink"] == n // 4 - 1
    work = (np.arange(n) % 5 + 1) * 100_000
    held = work[3:-1:4] + 1_000_000 + work[4::4]
    for key, ns in {"turns.turn": held, "poser.pose": held + 2_000_000}.items():
        lat = summary.latency[key]
        assert lat["count"] == ns.size and lat["max_ms"] == pytest.approx(ns.max() / 1e6)
        assert lat["median_ms"] == pytest.approx(np.quantile(ns, 0.5, method="lower") / 1e6, rel=0.016)


def test_work_origin_is_none_offline_and_setting_it_does_nothing() -> None:
    HeldTurns.ready = None
    src, turns, sink = Ticks("src", n=12), HeldTurns("turns"), CollectingSink("sink")
    summary = OfflineExecutor(make_net(src, turns, sink, connections=["src.out -> turns.x",
                                                                       "turns.turn -> sink.x"])).run()
    assert turns.origins_offline == [None] * 12 and summary.latency == {}
    assert sink.values() == [(0.0, 1.0, 2.0, 3.0), (4.0, 5.0, 6.0, 7.0)]


def test_offline_reports_no_latency() -> None:
    src, sink = Ticks("src", n=10), CollectingSink("sink")
    summary = OfflineExecutor(make_net(src, sink, connections=["src.out -> sink.x"])).run()
    assert summary.latency == {} and "LATENCY" not in summary.format()
    assert summary.to_json()["timing"]["sink"]["calls"] == 10


# --- a slow stage drops whole turns -------------------------------------------------------
class TurnImages(Source):
    """Non-live: ``n`` turn images (each filled with its index), released at once; ``sent`` after the last."""

    out = Output(np.ndarray)
    n = Param(int, default=12)
    size = Param(int, default=64)
    sent: threading.Event | None = None

    def generate(self):
        for i in range(self.n):
            yield i * 250_000_000, "out", np.full((self.size, self.size), i, dtype=np.float32)
        self.sent.set()  # type: ignore[union-attr]


class SlowSlam(Component):
    """A slow consumer of turn images (waits for ``gate`` before taking each one)."""

    image = Input(np.ndarray)
    pose = Output(float)
    gate: threading.Event | None = None

    def start(self) -> None:
        self.seen: list[np.ndarray] = []

    def process(self, t: int) -> None:
        assert self.gate.wait(HANG_S)  # type: ignore[union-attr]
        img = self.image.take()
        self.seen.append(img)
        self.pose.emit(t, float(img[0, 0]))


@pytest.mark.parametrize("bound", ["maxsize: 1", "maxbytes: 20000"])
def test_a_bounded_slow_stage_drops_whole_turns_and_counts_them(bound: str) -> None:
    n = 12
    sent = threading.Event()
    TurnImages.sent = SlowSlam.gate = sent      # the consumer takes nothing before every turn was pushed
    session = Session(extra_plugins={"t": plugin_of(TurnImages, SlowSlam, CollectingSink)}, entrypoints=False)
    spec = session.load_text(textwrap.dedent(f"""
        name: slow
        clock: {{mode: realtime}}
        components:
          src: {{type: t.TurnImages, params: {{n: {n}}}}}
          slam: {{type: t.SlowSlam, inputs: {{image: {{{bound}, overflow: drop_oldest}}}}}}
          sink: {{type: t.CollectingSink}}
        connections:
          - src.out -> slam.image
          - slam.pose -> sink.x
    """))
    net = session.build(spec)
    slam = net.components["slam"]
    summary = run_thread(lambda: session.run(net, mode="realtime"))
    st = summary.inputs["slam.image"]
    dropped = st["dropped"] + st["dropped_maxbytes"]
    # the first process() call waits while every turn is pushed: one turn (64x64 float32,
    # 16 KiB) fits the input, the newest; the others were dropped whole, never cut
    assert st["received"] == n and dropped == n - 1 and summary.processed["slam"] == 1
    assert summary.drops() == {"slam.image": {("dropped" if "maxsize" in bound else "dropped_maxbytes"): n - 1}}
    (img,) = slam.seen
    assert img.shape == (64, 64) and (img == n - 1).all()        # the newest turn, whole
    assert net.components["sink"].values() == [float(n - 1)]
    assert any(line.startswith("  LOST at slam.image: 11 dropped") for line in summary.format().splitlines())


def test_the_same_bounded_input_offline_drops_nothing() -> None:
    """Offline the executor runs the stage on each turn before reading the next: every turn is processed."""
    n = 12
    gate = threading.Event()
    gate.set()
    TurnImages.sent, SlowSlam.gate = threading.Event(), gate
    session = Session(extra_plugins={"t": plugin_of(TurnImages, SlowSlam, CollectingSink)}, entrypoints=False)
    spec = session.load_text(textwrap.dedent(f"""
        name: slow-offline
        components:
          src: {{type: t.TurnImages, params: {{n: {n}}}}}
          slam: {{type: t.SlowSlam, inputs: {{image: {{maxsize: 1, overflow: drop_oldest}}}}}}
          sink: {{type: t.CollectingSink}}
        connections:
          - src.out -> slam.image
          - slam.pose -> sink.x
    """))
    net = session.build(spec)
    assert net.components["slam"].inputs["image"].maxsize == 1
    summary = session.run(net)
    assert summary.drops() == {} and net.components["sink"].values() == [float(i) for i in range(n)]
    assert spec.resolved()["components"]["slam"]["inputs"] == {"image": {"maxsize": 1, "overflow": "drop_oldest"}}


def test_graph_input_bounds_are_checked_and_located() -> None:
    session = Session(extra_plugins={"t": plugin_of(TurnImages, SlowSlam)}, entrypoints=False)
    _, problems = session.problems("g.yaml", text=textwrap.dedent("""
        clock: {mode: realtime}
        components:
          src: {type: t.TurnImages}
          slam: {type: t.SlowSlam, inputs: {imgae: {maxsize: 1}, image: {maxsize: 0, overflow: drop_old, size: 3}}}
        connections:
          - src.out -> slam.image
    """))
    msgs = sorted(str(p) for p in problems)
    assert any("input 'image': maxsize must be an integer >= 1 (samples), got 0" in m for m in msgs), msgs
    assert any("overflow must be one of block, drop_oldest, drop_newest, got 'drop_old'" in m for m in msgs), msgs
    assert any("unknown key 'size' in component 'slam', input 'image'" in m for m in msgs), msgs
    assert any("inputs: no input 'imgae' (did you mean 'image'?)" in m for m in msgs), msgs
    assert all(m.startswith("g.yaml:") for m in msgs), msgs


def test_an_includer_refines_an_included_components_input_bounds(tmp_path) -> None:
    (tmp_path / "base.yaml").write_text(textwrap.dedent("""
        components:
          src: {type: t.TurnImages}
          slam: {type: t.SlowSlam, inputs: {image: {maxsize: 4}}}
        connections:
          - src.out -> slam.image
    """))
    (tmp_path / "live.yaml").write_text(textwrap.dedent("""
        include: base.yaml
        clock: {mode: realtime}
        components:
          slam: {inputs: {image: {overflow: drop_oldest}}}
    """))
    session = Session(extra_plugins={"t": plugin_of(TurnImages, SlowSlam)}, entrypoints=False)
    port = session.build(session.load(tmp_path / "live.yaml")).components["slam"].inputs["image"]
    assert (port.maxsize, port.overflow) == (4, "drop_oldest")
    _, problems = session.problems("g.yaml", text="components:\n  slam: {type: t.SlowSlam, inputs: [image]}\n")
    assert any("g.yaml:2:" in str(p) and "inputs must be a mapping" in str(p) for p in problems), problems
