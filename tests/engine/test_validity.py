"""Input-sample validity (issue 24, "finite or refused"): a message whose ``invalid_reason()``
says it is not finite or impossible is dropped where it enters an input, counted per input
and reason, logged once per reason, and never reaches the component."""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from impala_flow import Component, Input, Output
from impala_flow.msgs import Grid, Pose2D
from impala_flow.testing import CollectingSink, ScriptedSource, run_components, run_graph_text
from impala_msgs import RadarBeam, RadarDetections, Speed
from impala_radar.simulator.presets import IMPALA

MS = 1_000_000


def _pose(x=0.0, cov=None):
    return Pose2D(x, 0.0, 0.0, np.eye(3) if cov is None else cov)


def test_invalid_samples_are_dropped_counted_by_reason_and_logged_once(caplog):
    bad_cov = np.eye(3)
    bad_cov[1, 1] = np.inf
    samples = [(0, "p", _pose(1.0)), (1 * MS, "p", _pose(np.nan)), (2 * MS, "p", _pose(np.nan)),
               (3 * MS, "p", _pose(2.0, bad_cov)), (4 * MS, "p", _pose(np.nan)), (5 * MS, "p", _pose(3.0))]
    sink = CollectingSink("sink")
    with caplog.at_level(logging.WARNING):
        summary = run_components(ScriptedSource("src", samples), sink, connections=["src.p -> sink.x"])
    assert [p.x_m for p in sink.values()] == [1.0, 3.0]
    st = summary.inputs["sink.x"]
    assert st["received"] == 6 and st["invalid"] == 4
    assert st["invalid_reasons"] == {"non-finite x_m": 3, "non-finite cov_xyt": 1}
    assert summary.drops() == {"sink.x": {"invalid": 4}} and summary.total_lost == 4
    warned = [r.getMessage() for r in caplog.records if "invalid" in r.getMessage()]
    assert len(warned) == 2  # one line per reason, not per sample
    assert "input 'x'" in warned[0] and "t=1000000 ns" in warned[0] and "src.p" in warned[0]
    assert "non-finite x_m" in warned[0] and "non-finite cov_xyt" in warned[1]
    text = summary.format()
    lines = [ln for ln in text.splitlines() if "INVALID" in ln]
    assert lines == ["  INVALID at sink.x: 4 samples dropped on arrival (non-finite x_m: 3, non-finite cov_xyt: 1)"]
    assert "no sample dropped" not in text


class Keeper(Component):
    """Keeps what reaches it; one input checked (the default), one not."""

    checked = Input(object)
    raw = Input(object, validate=False)

    def start(self):
        self.got = {"checked": [], "raw": []}

    def process(self, t):
        self.got[self.trigger].append(self.inputs[self.trigger].take())


def test_validate_false_passes_every_sample():
    samples = [(0, "a", _pose(np.nan)), (1, "a", _pose(1.0))]
    k = Keeper("k")
    summary = run_components(ScriptedSource("src", samples), k, connections=["src.a -> k.checked", "src.a -> k.raw"])
    assert len(k.got["raw"]) == 2 and len(k.got["checked"]) == 1
    assert summary.inputs["k.raw"]["invalid"] == 0 and summary.inputs["k.checked"]["invalid"] == 1


class Policies(Component):
    """A sync pair and a sampling input with history: invalid samples never enter either."""

    a = Input(Pose2D, sync="ab", tolerance=0.0005)
    b = Input(Pose2D, sync="ab", tolerance=0.0005)
    level = Input(Pose2D, policy="sampling", history=1.0)
    out = Output(object)

    def process(self, t):
        a, b = self.a.take(), self.b.take()
        self.out.emit(t, (a.x_m, b.x_m, self.level.at(t, clamp=True).x_m))


def test_invalid_samples_never_enter_sync_groups_sampling_or_history():
    samples = []
    for k in range(4):
        samples += [(k * MS, "lvl", _pose(float(k) if k != 2 else np.inf)),
                    (k * MS, "a", _pose(float(k) if k != 1 else np.nan)),
                    (k * MS, "b", _pose(10.0 + k))]
    comp, sink = Policies("c"), CollectingSink("sink")
    summary = run_components(ScriptedSource("src", samples), comp, sink, connections=[
        "src.a -> c.a", "src.b -> c.b", "src.lvl -> c.level", "c.out -> sink.x"])
    # a@1 ms invalid: b@1 ms is unmatched; level@2 ms invalid: at(2 ms) holds the level of 1 ms
    assert sink.values() == [(0.0, 10.0, 0.0), (2.0, 12.0, 1.0), (3.0, 13.0, 3.0)]
    assert summary.inputs["c.a"]["invalid"] == 1 and summary.inputs["c.b"]["unmatched"] == 1
    assert summary.inputs["c.level"]["invalid_reasons"] == {"non-finite x_m": 1}


def test_message_checks():
    assert _pose().invalid_reason() is None
    # NaN means "unknown" in the fields declared so; inf never
    assert Speed(3.0).invalid_reason() is None and Speed(np.inf).invalid_reason() == "non-finite speed_mps"
    nan = np.full(2, np.nan)
    i2 = np.zeros(2, np.int64)
    det = RadarDetections(0, i2, i2, np.zeros(2), np.ones(2), nan, np.ones(2), nan)
    assert det.invalid_reason() is None
    det.radial_speed_mps = np.array([1.0, -np.inf])
    assert det.invalid_reason() == "non-finite radial_speed_mps"
    det.range_m = np.array([1.0, np.nan])
    assert det.invalid_reason() == "non-finite range_m"
    # impossible values of nested messages name the field they came through
    beam = RadarBeam(0.0, 0, 0, np.ones(4, np.float32), np.zeros(0, np.float32), replace(IMPALA, bandwidth_hz=0.0))
    assert beam.invalid_reason() == "config: bandwidth_hz <= 0"
    assert Grid(np.zeros((2, 2)), 0.0, 0.0, 0.0).invalid_reason() == "cell_m <= 0"
    # a float32 array whose sum overflows is still finite: the exact check decides
    big = np.full(8, 3e38, np.float32)
    assert Grid(big.reshape(2, 4), 1.0, 0.0, 0.0).invalid_reason() is None


def test_graph_run_reports_invalid_samples():
    text = """
name: validity
components:
  src: {type: test.ScriptedSource}
  sink: {type: test.CollectingSink}
connections: ["src.out -> sink.x"]
"""

    class Src(ScriptedSource):
        def generate(self):
            for k in range(10):
                yield k * MS, "out", Speed(np.nan if k % 3 == 0 else float(k))

    Src.__name__ = "ScriptedSource"
    summary, net = run_graph_text(text, Src, CollectingSink)
    assert [s.speed_mps for s in net.components["sink"].values()] == [1.0, 2.0, 4.0, 5.0, 7.0, 8.0]
    assert summary.invalid() == {"sink.x": {"non-finite speed_mps": 4}}


def test_real_time_executor_drops_and_counts_invalid_samples_too():
    from .test_runtime import make_net, run_rt

    samples = [(k * MS, "p", _pose(np.nan if k % 4 == 1 else float(k))) for k in range(12)]
    sink = CollectingSink("sink")
    summary = run_rt(make_net(ScriptedSource("src", samples), sink, connections=["src.p -> sink.x"]))
    assert [p.x_m for p in sink.values()] == [float(k) for k in range(12) if k % 4 != 1]
    assert summary.invalid() == {"sink.x": {"non-finite x_m": 3}}


def test_impossible_shapes_and_values_are_invalid():
    from impala_msgs import ObjectStates, RadarScan, TrackExistence

    ids = np.array([1, 2])
    assert ObjectStates(ids, np.zeros((2, 2)), np.zeros((2, 2))).invalid_reason() is None
    assert ObjectStates(ids, np.zeros((3, 2)), np.zeros((2, 2))).invalid_reason() == \
        "ids, xy_m, v_xy_mps, cov rows do not match"
    assert TrackExistence(ids, np.zeros((2, 2)), np.array([0.5, 1.5]), np.ones(2, bool)).invalid_reason() == \
        "probability outside [0, 1]"
    assert Pose2D(0.0, 0.0, 0.0, np.eye(2)).invalid_reason() == "cov_xyt neither empty nor 3 x 3"
    assert Grid(np.zeros(4), 1.0, 0.0, 0.0).invalid_reason() == "data not 2-D"
    scan = RadarScan(0, np.zeros(3, np.int64), np.zeros(3), np.zeros((2, 8)), np.zeros(0), IMPALA)
    assert scan.invalid_reason() == "t_ns, azimuth_rad and power rows differ in length"


def test_a_check_that_cannot_read_the_sample_makes_it_invalid_not_a_crash():
    from impala_msgs import ObjectStates

    bad = ObjectStates(None, np.zeros((1, 2)), np.zeros((1, 2)))  # len(None) raises inside the check
    good = ObjectStates(np.array([1]), np.zeros((1, 2)), np.zeros((1, 2)))
    sink = CollectingSink("sink")
    summary = run_components(ScriptedSource("src", [(0, "p", bad), (1, "p", good)]), sink,
                             connections=["src.p -> sink.x"])
    assert sink.values() == [good]
    assert summary.invalid() == {"sink.x": {"unreadable (TypeError)": 1}}


def test_a_fanned_out_invalid_sample_is_counted_at_every_input_it_reaches():
    samples = [(0, "p", _pose(np.inf)), (1, "p", _pose(1.0))]
    a, b = CollectingSink("a"), CollectingSink("b")
    summary = run_components(ScriptedSource("src", samples), a, b, connections=["src.p -> a.x", "src.p -> b.x"])
    assert summary.invalid() == {"a.x": {"non-finite x_m": 1}, "b.x": {"non-finite x_m": 1}}
    assert len(a.values()) == len(b.values()) == 1


def _turn_beams(power, t0=0):
    empty = np.zeros(0, np.float32)
    return [(t0 + i * MS, "p", RadarBeam(0.01 * i, 0, i, power[i], empty, IMPALA)) for i in range(len(power))]


def test_beams_of_a_frozen_turn_are_checked_by_the_turn_and_still_dropped_one_by_one():
    """A reader's frozen turn (the beams are its rows) is tested once for finiteness; a turn holding a NaN or an
    inf drops exactly its bad beams, wherever it comes among finite turns, frozen or not."""
    rng = np.random.default_rng(4)
    turns = []
    for k, bad in enumerate([(), (3,), (), (0, 5), ()]):
        p = rng.random((8, 600)).astype(np.float32)
        for i in bad:
            p[i, 7 * i] = np.nan if i % 2 else np.inf
        p.flags.writeable = k == 4  # the last turn left writeable: checked beam by beam
        if k in (0, 1):  # as a reader does on its reading thread: the turn checked (and remembered if finite)
            assert RadarBeam.check_turn(p) is (k == 0)
        turns.append(p)
    samples = [s for k, p in enumerate(turns) for s in _turn_beams(p, k * 100 * MS)]
    sink = CollectingSink("sink")
    summary = run_components(ScriptedSource("src", samples), sink, connections=["src.p -> sink.x"])
    kept = [(b.turn, b.index) for b in sink.values()]
    assert len(kept) == 40 - 3
    assert [k for k, p in enumerate(turns) for i in range(8) if not np.isfinite(p[i]).all()] == [1, 3, 3]
    assert summary.inputs["sink.x"]["invalid_reasons"] == {"non-finite up": 3}
    # the same beams one by one (each a copy of its row: no turn to lean on) give the same verdicts
    for p in turns:
        for i in range(8):
            alone = RadarBeam(0.0, 0, i, p[i].copy(), np.zeros(0, np.float32), IMPALA)
            lean = RadarBeam(0.0, 0, i, p[i], np.zeros(0, np.float32), IMPALA)
            assert alone.invalid_reason() == lean.invalid_reason() == (
                None if np.isfinite(p[i]).all() else "non-finite up")


def test_a_remembered_turn_never_vouches_for_another_array():
    """Turns are remembered by weak reference under their id: once a finite turn is gone, a new turn (whatever
    its address) is checked itself, and a writeable turn is never remembered."""
    empty = np.zeros(0, np.float32)
    for _ in range(50):
        p = np.ones((4, 600), np.float32)
        p.flags.writeable = False
        assert RadarBeam.check_turn(p)
        del p
        q = np.ones((4, 600), np.float32)
        q[2, 5] = np.nan
        q.flags.writeable = False
        assert RadarBeam(0.0, 0, 2, q[2], empty, IMPALA).invalid_reason() == "non-finite up"
        assert RadarBeam(0.0, 0, 1, q[1], empty, IMPALA).invalid_reason() is None
    w = np.ones((4, 600), np.float32)
    assert RadarBeam.check_turn(w)
    w[3, 0] = np.inf  # still writeable: nothing was remembered of it
    assert RadarBeam(0.0, 0, 3, w[3], empty, IMPALA).invalid_reason() == "non-finite up"
