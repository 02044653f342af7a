"""Sweep files: the issue's minimal example, tasks and their ids, and every problem reported
on one line with file:line:col (and, for the checks against the graph, before any cluster
starts: exit 2)."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import pytest

from impala_flow._load import parse_set
from impala_sweep.spec import SweepError, load_sweep

from .conftest import GRAPH, ROOT, sweep_main

MINIMAL = """\
graph: graphs/rslam.yaml
missions: {simulate: {scenario: beynes, duration_s: 20, seeds: [1, 2]}}
grid: {slam.search_m: [1.0, 2.0]}
metrics: [eval.ate_rmse_m, eval.drift_pct]
"""


def test_the_issues_minimal_example(tmp_path: Path) -> None:
    (tmp_path / "graphs").symlink_to(ROOT / "graphs")  # the example's path, relative to the sweep file
    path = tmp_path / "sweep.yaml"
    path.write_text(MINIMAL, encoding="utf-8")
    spec = load_sweep(path)
    assert spec.graph.resolve() == GRAPH
    assert spec.metrics == ["eval.ate_rmse_m", "eval.drift_pct"]
    assert spec.param_names == ["slam.search_m"]
    assert [(t.mission, t.seed, t.duration_s, t.params) for t in spec.tasks] == [
        ("sim:beynes", 1, 20.0, (("slam.search_m", 1.0),)), ("sim:beynes", 1, 20.0, (("slam.search_m", 2.0),)),
        ("sim:beynes", 2, 20.0, (("slam.search_m", 1.0),)), ("sim:beynes", 2, 20.0, (("slam.search_m", 2.0),))]
    assert [t.id for t in spec.tasks] == ["beynes_s1_slam.search_m=1.0", "beynes_s1_slam.search_m=2.0",
                                          "beynes_s2_slam.search_m=1.0", "beynes_s2_slam.search_m=2.0"]
    assert spec.variants == ["slam.search_m=1.0", "slam.search_m=2.0"]


def test_product_variants_files_repeats(tmp_path: Path, write_sweep: Callable[..., Path]) -> None:
    for name in ("a.mcap", "b.mcap", "sub/a.mcap"):
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_bytes(b"")
    spec = load_sweep(write_sweep(f"""\
graph: {GRAPH}
missions: {{files: ["*.mcap", a.mcap, sub/*.mcap]}}
grid: {{slam.search_m: [1.0, 2.0], slam.map_update: [weighted, paper]}}
metrics: [eval.ate_rmse_m]
repeats: 2
"""))
    missions = sorted({t.mission for t in spec.tasks})
    assert missions == sorted(str((tmp_path / n).resolve()) for n in ("a.mcap", "b.mcap", "sub/a.mcap"))
    assert len(spec.tasks) == 3 * 4 * 2  # a.mcap matched twice runs once
    assert len({t.id for t in spec.tasks}) == len(spec.tasks)
    ids = {t.id for t in spec.tasks}
    # two files named a.mcap: told apart by their path
    assert "a_slam.search_m=1.0_slam.map_update=paper_r1" in ids
    assert "sub-a_slam.search_m=1.0_slam.map_update=paper_r1" in ids
    spec = load_sweep(write_sweep(f"""\
graph: {GRAPH}
missions:
  simulate: [{{scenario: beynes, seeds: 3}}, {{scenario: urban, duration_s: 5, seeds: [4, 5]}}]
variants: [{{}}, {{slam.search_m: 0.5, slam.map_update: paper}}]
metrics: [eval.ate_rmse_m]
""", "v.yaml"))
    assert [(t.mission, t.seed, t.variant) for t in spec.tasks] == [
        ("sim:beynes", 3, "default"), ("sim:beynes", 3, "slam.map_update=paper, slam.search_m=0.5"),
        ("sim:urban", 4, "default"), ("sim:urban", 4, "slam.map_update=paper, slam.search_m=0.5"),
        ("sim:urban", 5, "default"), ("sim:urban", 5, "slam.map_update=paper, slam.search_m=0.5")]


@pytest.mark.parametrize("value", [1.0, 2, "paper", "1.0", "true", [1, 2.5], {"a": 1}, True, "with space", 1e-4])
def test_a_variant_reaches_the_graph_with_its_type(value: object, write_sweep: Callable[..., Path]) -> None:
    import json

    spec = load_sweep(write_sweep(f"graph: {GRAPH}\nmissions: {{simulate: {{scenario: beynes}}}}\n"
                                  f"grid: {{slam.x: [{json.dumps(value)}]}}\nmetrics: [eval.a]\n"))
    (item,) = spec.tasks[0].overrides()
    assert parse_set(item) == ("slam", "x", value)
    assert type(parse_set(item)[2]) is type(value)
    assert re.fullmatch(r"[A-Za-z0-9._=+~-]+", spec.tasks[0].id)


BAD = [
    # (sweep file, line, column, what the message says)
    ("graph: G\nmissions: {simulate: {scenario: beynes}}\ngrids: {slam.search_m: [1]}\nmetrics: [eval.a]\n",
     3, 1, "unknown key 'grids'"),
    ("graph: G\nmissions: {simulate: {scenario: beynes}}\n", 1, 1, "missing key 'metrics'"),
    ("graph: nope/rslam.yaml\nmissions: {simulate: {scenario: beynes}}\nmetrics: [eval.a]\n", 1, 8,
     "no such file"),
    ("graph: G\nmissions: {simulate: {scenario: beynes}}\nmetrics:\n  - eval.a\n  - ate_rmse_m\n", 5, 5,
     "'ate_rmse_m' is not 'component.key'"),
    ("graph: G\nmissions: {simulate: {scenario: beynes}}\nmetrics: [eval.a, eval.a]\n", 3, 19, "listed twice"),
    ("graph: G\nmissions: {simulate: {scenario: beynes}}\ngrid: {slam.search_m: 1.0}\nmetrics: [eval.a]\n",
     3, 23, "non-empty list"),
    ("graph: G\nmissions: {simulate: {scenario: beynes}}\ngrid:\n  search_m: [1.0]\nmetrics: [eval.a]\n",
     4, 3, "'search_m' is not 'component.param'"),
    ("graph: G\nmissions: {simulate: {scenario: beynes}}\ngrid: {slam.search_m: [1.0, 1.0]}\nmetrics: [eval.a]\n",
     3, 29, "listed twice"),
    ("graph: G\nmissions:\n  simulate: {scenario: beynes, seeds: [1, one]}\nmetrics: [eval.a]\n", 3, 43,
     "seed 'one' is not an integer"),
    ("graph: G\nmissions:\n  simulate: {scenario: beynes, duration_s: -3}\nmetrics: [eval.a]\n", 3, 44,
     "duration_s must be a positive number"),
    ("graph: G\nmissions:\n  simulate: {seeds: [1]}\nmetrics: [eval.a]\n", 3, 13, "needs a scenario"),
    ("graph: G\nmissions:\n  simulate: {scenario: beynes, seed: [1]}\nmetrics: [eval.a]\n", 3, 32,
     "unknown key missions.simulate.seed"),
    ("graph: G\nmissions:\n  simulate: {scenario: scenarios/nope.yaml}\nmetrics: [eval.a]\n", 3, 24,
     "scenario file"),
    ("graph: G\nmissions:\n  files:\n    - '*.mcap'\n    - nothing/*.mcap\nmetrics: [eval.a]\n", 5, 7,
     "matches no file"),
    ("graph: G\nmissions: {recorded: [a.mcap]}\nmetrics: [eval.a]\n", 2, 12, "unknown key missions.recorded"),
    ("graph: G\nmissions: {simulate: {scenario: beynes}}\nmetrics: [eval.a]\nrepeats: 0\n", 4, 10,
     "repeats must be an integer >= 1"),
    ("graph: G\nmissions: {simulate: {scenario: beynes}}\nmetrics: [eval.a]\nvariables: {out: x}\n", 4, 13,
     "'out' is set by the sweep"),
    ("graph: G\nmissions: {simulate: {scenario: beynes}}\ngrid: {a.b: [1]}\nvariants: [{a.b: 1}]\n"
     "metrics: [eval.a]\n", 4, 1, "either grid"),
    ("graph: G\nmissions: {simulate: {scenario: beynes}}\nvariants: [{a.b: 1}, 3]\nmetrics: [eval.a]\n", 3, 22,
     "variant 2 must be a mapping"),
    ("graph: G\nmissions: {simulate: {scenario: beynes}}\nmetrics: [eval.a]\nmetrics: [eval.b]\n", 4, 1,
     "duplicate key"),
    ("graph: G\nmissions: {simulate: {scenario: beynes}\nmetrics: [eval.a]\n", 3, 1, "invalid YAML"),
]


@pytest.mark.parametrize(("text", "line", "col", "says"), BAD)
def test_bad_sweep_files_are_located(text: str, line: int, col: int, says: str, tmp_path: Path,
                                     write_sweep: Callable[..., Path]) -> None:
    (tmp_path / "a.mcap").write_bytes(b"")
    path = write_sweep(text.replace("graph: G", f"graph: {GRAPH}"))
    with pytest.raises(SweepError) as e:
        load_sweep(path)
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith(f"{path}:{line}:{col}: "), msg
    assert says in msg


def _sweep(write_sweep: Callable[..., Path], grid: str = "{slam.search_m: [1.0]}",
           metrics: str = "[eval.ate_rmse_m]", extra: str = "") -> Path:
    return write_sweep(f"graph: {GRAPH}\nmissions: {{simulate: {{scenario: beynes, duration_s: 4}}}}\n"
                       f"grid: {grid}\nmetrics: {metrics}\n{extra}")


@pytest.mark.parametrize(("grid", "metrics", "extra", "line", "col", "says"), [
    ("{slamm.search_m: [1.0]}", "[eval.ate_rmse_m]", "", 3, 8,
     "slamm.search_m: no component 'slamm' in graph rslam.yaml (did you mean 'slam'?)"),
    ("{slam.serch_m: [1.0]}", "[eval.ate_rmse_m]", "", 3, 8,
     "slam.serch_m: slam.RSlam has no parameter 'serch_m' (did you mean 'search_m'?)"),
    ("{slam.search_m: [1.0]}", "[evaluator.ate_rmse_m]", "", 4, 11,
     "metric evaluator.ate_rmse_m: no component 'evaluator' in graph rslam.yaml (did you mean 'eval'?)"),
])
def test_names_are_checked_against_the_graph_before_anything_runs(
        grid: str, metrics: str, extra: str, line: int, col: int, says: str, write_sweep: Callable[..., Path],
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _sweep(write_sweep, grid, metrics, extra)
    assert sweep_main(str(path), "-o", str(tmp_path / "out")) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"impala-flow sweep: error: {path}:{line}:{col}: {says}"
    assert not (tmp_path / "out").exists()  # nothing started, nothing written


def test_an_invalid_graph_stops_the_sweep_before_it_starts(write_sweep: Callable[..., Path], tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(GRAPH.read_text(encoding="utf-8").replace("type: slam.RSlam", "type: slam.RSlamm"))
    path = write_sweep(f"graph: {bad}\nmissions: {{simulate: {{scenario: beynes}}}}\nmetrics: [eval.ate_rmse_m]\n")
    assert sweep_main(str(path), "-o", str(tmp_path / "out")) == 2
    err = capsys.readouterr().err
    assert f"{bad}:15:" in err and "slam.RSlamm" in err and "slam.RSlam" in err


def test_usage_errors(write_sweep: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _sweep(write_sweep)
    out = tmp_path / "out"
    assert sweep_main(str(path)) == 2
    assert "-o DIR" in capsys.readouterr().err
    assert sweep_main(str(path), "--resume", str(out)) == 2
    assert "nothing to resume" in capsys.readouterr().err
    assert sweep_main(str(path), "-o", str(out), "--scheduler", "tcp://127.0.0.1:1", "--workers", "2") == 2
    assert "--workers" in capsys.readouterr().err
    out.mkdir()
    (out / "results.csv").write_text("task\n")
    assert sweep_main(str(path), "-o", str(out)) == 2
    err = capsys.readouterr().err
    assert "is not empty and is not a sweep's" in err and "--overwrite" in err
    assert sweep_main(str(path), "--resume", str(out)) == 2
    assert "not a sweep folder" in capsys.readouterr().err
    assert (out / "results.csv").read_text() == "task\n"
    assert sweep_main(str(tmp_path / "missing.yaml"), "-o", str(out)) == 2
    assert "missing.yaml: cannot read" in capsys.readouterr().err
