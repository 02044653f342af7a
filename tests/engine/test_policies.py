"""Input policies: reactive, sampling, sync groups, history look-ups, overflow counters."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impala_flow import Component, Input, OutOfHistory, Output, Periodic
from impala_flow.msgs import Pose2D
from impala_flow.testing import CollectingSink, ScriptedSource, run_components

MS = 1_000_000


class Latch(Component):
    """Reactive 'trigger', sampling 'level': emits the last level at each trigger."""

    trigger_in = Input(float)
    level = Input(float, policy="sampling")
    out = Output(object)

    def process(self, t):
        self.trigger_in.take()
        self.out.emit(t, self.level.get())


def test_sampling_input_never_triggers_and_holds_the_last_value():
    src = ScriptedSource("src", [(0, "lvl", 1.0), (1, "trg", 0.0), (2, "lvl", 2.0), (3, "lvl", 3.0),
                                 (4, "trg", 0.0), (5, "lvl", 4.0)])
    latch, sink = Latch("latch"), CollectingSink("sink")
    summary = run_components(src, latch, sink, connections=[
        "src.lvl -> latch.level", "src.trg -> latch.trigger_in", "latch.out -> sink.x"])
    assert sink.values() == [1.0, 3.0]
    assert summary.processed["latch"] == 2  # four level samples triggered nothing


class Pair(Component):
    a = Input(float, sync="ab", tolerance=0.002)
    b = Input(float, sync="ab", tolerance=0.002)
    out = Output(object)

    def process(self, t):
        assert self.trigger == "ab"
        sa, sb = self.a.take_sample(), self.b.take_sample()
        self.out.emit(max(sa.timestamp, sb.timestamp), (sa.data, sb.data))


def test_sync_group_pairs_within_tolerance_and_counts_the_unmatched():
    # a at 0,10,20,30,40 ms; b at 1,21,22(extra),41 ms and nothing near 10 or 30
    script = [(i * 10 * MS, "a", float(i)) for i in range(5)]
    script += [(1 * MS, "b", 100.0), (21 * MS, "b", 102.0), (22 * MS, "b", 999.0), (41 * MS, "b", 104.0)]
    script.sort(key=lambda s: s[0])
    pair, sink = Pair("pair"), CollectingSink("sink")
    summary = run_components(ScriptedSource("src", script), pair, sink,
                             connections=["src.a -> pair.a", "src.b -> pair.b", "pair.out -> sink.x"])
    assert sink.values() == [(0.0, 100.0), (2.0, 102.0), (4.0, 104.0)]
    # a@10 and a@30 found no partner, b@22 came second to a@20: each counted, none silently lost
    assert summary.inputs["pair.a"]["unmatched"] == 2
    assert summary.inputs["pair.b"]["unmatched"] == 1
    assert summary.drops() == {"pair.a": {"unmatched": 2}, "pair.b": {"unmatched": 1}}


def test_sync_group_when_one_stream_stops_leftovers_are_reported():
    script = [(i * MS, "a", float(i)) for i in range(6)] + [(0, "b", 0.0), (1 * MS, "b", 1.0)]
    script.sort(key=lambda s: s[0])
    sink = CollectingSink("sink")
    summary = run_components(ScriptedSource("src", script), Pair("pair"), sink,
                             connections=["src.a -> pair.a", "src.b -> pair.b", "pair.out -> sink.x"])
    assert len(sink.values()) == 2
    assert summary.inputs["pair.a"]["unmatched"] == 4  # a@2..5 ms waited for b, which stopped


class AtBeams(Component):
    """For each 'query' sample, looks the pose and heading up at the query's time."""

    query = Input(float)
    pose = Input(Pose2D, policy="sampling", history=1.0)
    heading = Input(float, policy="sampling", history=1.0, angular=True)
    out = Output(object)

    def process(self, t):
        self.query.take()
        try:
            self.out.emit(t, (self.pose.at(t), self.heading.at(t)))
        except OutOfHistory as e:
            self.out.emit(t, str(e))


def test_history_interpolates_linearly_and_angles_along_the_shortest_arc():
    p0 = Pose2D(0.0, 0.0, math.radians(170))
    p1 = Pose2D(10.0, -4.0, math.radians(-170))
    script = [(0, "pose", p0), (0, "heading", math.radians(170)),
              (100 * MS, "pose", p1), (100 * MS, "heading", math.radians(-170)),
              (25 * MS, "q", 0.0)]
    script = [script[0], script[1], script[4], script[2], script[3], (100 * MS, "q", 0.0), (150 * MS, "q", 0.0)]
    # queries at 25 ms arrive before the second pose: give them after instead
    script = [(0, "pose", p0), (0, "heading", math.radians(170)), (100 * MS, "pose", p1),
              (100 * MS, "heading", math.radians(-170)), (100 * MS, "q", 0.0), (150 * MS, "q", 0.0)]
    comp, sink = AtBeams("at"), CollectingSink("sink")
    run_components(ScriptedSource("src", script), comp, sink, connections=[
        "src.pose -> at.pose", "src.heading -> at.heading", "src.q -> at.query", "at.out -> sink.x"])
    pose_100, head_100 = sink.values()[0]
    assert pose_100.x_m == 10.0 and head_100 == pytest.approx(math.radians(-170))
    assert "outside its history" in sink.values()[1]
    # direct look-ups in the middle: x, y linear; theta through +-180 deg, not through 0
    mid = comp.pose.at(25 * MS)
    assert (mid.x_m, mid.y_m) == pytest.approx((2.5, -1.0))
    assert abs(mid.theta_rad) == pytest.approx(math.radians(175))
    assert abs(comp.heading.at(50 * MS)) == pytest.approx(math.pi)
    assert [s.timestamp for s in comp.pose.between(0, 100 * MS)] == [0, 100 * MS]
    assert comp.pose.at(150 * MS, clamp=True).x_m == 10.0


def test_history_forgets_samples_older_than_its_window():
    script = [(i * 100 * MS, "pose", Pose2D(float(i), 0.0, 0.0)) for i in range(30)] + [(2_950 * MS, "q", 0.0)]
    comp, sink = AtBeams("at"), CollectingSink("sink")
    run_components(ScriptedSource("src", script), comp, sink,
                   connections=["src.pose -> at.pose", "src.q -> at.query", "at.out -> sink.x"])
    kept = comp.pose.between(0, 10**12)
    assert kept[-1].timestamp - kept[1].timestamp <= 1_000 * MS  # one sample before the window kept
    with pytest.raises(OutOfHistory):
        comp.pose.at(0)


class Slow(Component):
    """Takes one sample per 10 ms timer tick only, so its FIFO fills up."""

    x = Input(float, maxsize=3, overflow="drop_oldest")
    tick = Periodic(0.010)
    out = Output(float)

    def process(self, t):
        if self.trigger == "tick" and self.x.ready:
            self.out.emit(t, self.x.take())


@pytest.mark.parametrize("overflow, expected_first", [("drop_oldest", 7.0), ("drop_newest", 0.0)])
def test_overflow_policies_drop_and_count(overflow, expected_first):
    class S(Slow):
        x = Input(float, maxsize=3, overflow=overflow)

        def process(self, t):
            if self.trigger == "tick" and self.x.ready:
                self.out.emit(t, self.x.take())

    # 10 samples in the first millisecond; the timer drains one per tick at 0, 10, 20, ... ms
    script = [(i * 100_000 + 1, "out", float(i)) for i in range(10)] + [(50 * MS, "out", 99.0)]
    sink = CollectingSink("sink")
    summary = run_components(ScriptedSource("src", script), S("slow"), sink,
                             connections=["src.out -> slow.x", "slow.out -> sink.x"])
    assert summary.inputs["slow.x"]["dropped"] == 7
    # ticks at 10, 20, 30 ms take the 3 kept samples; the 50 ms sample arrives before the
    # 50 ms tick fires (equal-timestamp rule), which takes it
    assert summary.inputs["slow.x"]["unconsumed"] == 0
    assert summary.total_lost == 7
    assert sink.values()[0] == expected_first and sink.values()[-1] == 99.0
    assert sink.times() == [10 * MS, 20 * MS, 30 * MS, 50 * MS]
    assert "LOST at slow.x: 7 dropped" in summary.format()


def test_periodic_trigger_fires_on_mission_time_multiples():
    class Tick(Component):
        x = Input(float, required=False, policy="sampling")
        tick = Periodic("period_s")
        from impala_flow import Param as _P

        period_s = _P(float, default=0.25, gt=0)
        out = Output(int)

        def process(self, t):
            self.out.emit(t, t)

    script = [(100 * MS, "out", 0.0), (1_000 * MS, "out", 1.0)]
    sink = CollectingSink("sink")
    run_components(ScriptedSource("src", script), Tick("tick"), sink,
                   connections=["src.out -> tick.x", "tick.out -> sink.x"])
    assert sink.values() == [250 * MS, 500 * MS, 750 * MS, 1_000 * MS]


def test_equal_timestamps_keep_emission_order_then_graph_order():
    order = []

    class Rec(Component):
        x = Input(object)
        y = Output(object)

        def process(self, t):
            v = self.x.take()
            order.append((self.name, v))
            self.y.emit(t, v)

    script = [(0, "out", "a"), (0, "out", "b"), (0, "out", "c")]
    r1, r2 = Rec("r1"), Rec("r2")
    run_components(ScriptedSource("src", script), r1, r2, CollectingSink("sink"),
                   connections=["src.out -> r1.x", "r1.y -> r2.x", "r2.y -> sink.x"])
    # (timestamp, graph order, sequence): all of r1 before r2 at the same time, each in emission order
    assert order == [("r1", "a"), ("r1", "b"), ("r1", "c"), ("r2", "a"), ("r2", "b"), ("r2", "c")]


def test_arrays_interpolate_in_history():
    class Look(Component):
        q = Input(float)
        v = Input(np.ndarray, policy="sampling", history=10.0)
        out = Output(object)

        def process(self, t):
            self.q.take()
            self.out.emit(t, self.v.at(t - 50 * MS))

    script = [(0, "v", np.array([0.0, 10.0])), (100 * MS, "v", np.array([1.0, 30.0])), (100 * MS, "q", 0.0)]
    sink = CollectingSink("sink")
    run_components(ScriptedSource("src", script), Look("look"), sink,
                   connections=["src.v -> look.v", "src.q -> look.q", "look.out -> sink.x"])
    np.testing.assert_allclose(sink.values()[0], [0.5, 20.0])
