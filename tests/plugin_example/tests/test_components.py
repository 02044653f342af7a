"""Tests of the example plugin, written with the helpers impala-flow ships for plugin authors."""

from __future__ import annotations

import pytest
from impala_flow_example import Counter, CsvWriter, MovingAverage, Threshold
from impala_flow_example import plugin as example_plugin

from impala_flow.plugins import load_registry, make_plugin_manager
from impala_flow.testing import CollectingSink, ScriptedSource, run_components, run_graph_text

MS = 1_000_000  # ns


def test_counter_counts_at_its_rate() -> None:
    sink = CollectingSink("sink")
    run_components(Counter("c", rate=4.0, count=5, first=10, step=-2, t0_ns=7), sink,
                   connections=["c.value -> sink.x"])
    assert sink.values() == [10, 8, 6, 4, 2]
    assert sink.times() == [7, 7 + 250 * MS, 7 + 500 * MS, 7 + 750 * MS, 7 + 1000 * MS]


def test_moving_average_over_its_window() -> None:
    src = ScriptedSource("src", [(t * MS, "out", v) for t, v in enumerate([1, 2, 3, 4, 10])])
    sink = CollectingSink("sink")
    summary = run_components(src, MovingAverage("avg", window=3), sink,
                             connections=["src.out -> avg.x", "avg.mean -> sink.x"])
    assert sink.values() == [1.0, 1.5, 2.0, 3.0, 17 / 3]
    assert sink.times() == [0, MS, 2 * MS, 3 * MS, 4 * MS]  # emitted at each input sample's time
    assert summary.drops() == {}  # no input lost a sample


def test_threshold_samples_its_level_without_being_triggered() -> None:
    x = ScriptedSource("x", [(10, "out", 1.0), (20, "out", 5.0), (40, "out", 5.0), (50, "out", 9.0)])
    level = ScriptedSource("lvl", [(30, "out", 6.0)])
    sink = CollectingSink("sink")
    summary = run_components(x, level, Threshold("th", default_level=2.0), sink,
                             connections=["x.out -> th.x", "lvl.out -> th.level", "th.above -> sink.x"])
    # level 2.0 until t=30, then 6.0; the level sample itself triggers nothing
    assert sink.values() == [False, True, False, True]
    assert summary.processed["th"] == 4
    assert summary.extra["th"] == {"crossings": 3}


def test_paced_replay_waits_for_every_sample_time(fake_clock) -> None:  # fixture of impala_flow.testing
    sink = CollectingSink("sink")
    run_components(Counter("c", rate=2.0, count=3), sink, connections=["c.value -> sink.x"], clock=fake_clock)
    assert fake_clock.waits == [0, 500 * MS, 1000 * MS]


def test_parameters_are_validated() -> None:
    with pytest.raises(ValueError, match="window"):
        MovingAverage("avg", window=0)
    with pytest.raises(ValueError, match="rate"):
        Counter("c", rate=-1.0)


def test_plugin_registers_every_component() -> None:
    pm = make_plugin_manager({"example": example_plugin}, entrypoints=False)
    registry = load_registry(pm)
    assert sorted(registry.plugins["example"].components) == [
        "example.Counter", "example.CsvWriter", "example.MovingAverage", "example.Threshold",
    ]


def test_yaml_graph(tmp_path) -> None:
    out = tmp_path / "avg.csv"
    text = f"""
name: example
components:
  counter: {{type: ex.Counter, params: {{rate: 100.0, count: 4}}}}
  avg: {{type: ex.MovingAverage, params: {{window: 2}}}}
  csv: {{type: ex.CsvWriter, params: {{path: "{out}"}}}}
connections:
  - counter.value -> avg.x
  - avg.mean -> csv.x
"""
    summary, _ = run_graph_text(text, Counter, MovingAverage, CsvWriter, plugin="ex")
    assert out.read_text().splitlines() == ["t_ns,value", "0,0.0", "10000000,0.5", "20000000,1.5", "30000000,2.5"]
    assert summary.extra["csv"] == {"rows": 4}
