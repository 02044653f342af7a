"""impala-flow graph: DOT text that parses, and a PNG picture."""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable
from pathlib import Path

import pytest

from .conftest import Installed

Write = Callable[[str, str], Path]

RADAR = """\
name: radar-chain
components:
  sim: {type: clitest.RadarSim}
  pairer: {type: clitest.FuzzyPairer}
  doppler: {type: clitest.DopplerEgo}
  panoramic: {type: clitest.PanoramicBuilder}
  speckle: {type: clitest.SpeckleFilter}
  slam: {type: clitest.RSlam}
  tracker: {type: clitest.Tracker}
  eval: {type: clitest.TrajectoryEvaluator}
connections:
  - sim.beams -> pairer.beams
  - sim.beams -> panoramic.beams
  - sim.speed -> panoramic.speed
  - sim.yaw_rate -> panoramic.yaw_rate
  - pairer.targets -> doppler.targets
  - pairer.targets -> tracker.targets
  - doppler.ego -> tracker.ego
  - panoramic.image -> speckle.image
  - speckle.filtered -> slam.image
  - sim.speed -> slam.speed
  - slam.pose -> panoramic.pose [delay]
  - slam.pose -> eval.estimate
  - sim.gps -> eval.truth
  - {from: tracker.tracks, to: eval.tracks}
"""

NODE = re.compile(r'^  "(?P<id>[^"\\]+)" \[label="(?P<label>(?:[^"\\]|\\.)*)"\];$')
EDGE = re.compile(r'^  "(?P<a>[^"\\]+)":o(?P<o>\d+):e -> "(?P<b>[^"\\]+)":i(?P<i>\d+):w \[(?P<attrs>.*)\];$')


def _dot_edges_by_regex(dot: str) -> tuple[set[str], list[tuple[str, str, bool]]]:
    """A strict reading of the DOT this project writes: header, nodes, edges, closing brace."""
    lines = dot.rstrip("\n").splitlines()
    assert lines[0] == 'digraph "radar-chain" {' and lines[-1] == "}"
    nodes, edges = set(), []
    for line in lines[1:-1]:
        if m := NODE.match(line):
            label = m["label"]
            assert label.startswith("{") and label.endswith("}") and label.count("{") == label.count("}")
            nodes.add(m["id"])
        elif m := EDGE.match(line):
            edges.append((m["a"], m["b"], "style=dashed" in m["attrs"]))
        else:
            assert re.match(r"^  (rankdir|label|node|edge)\b.*;$", line), line
    return nodes, edges


def test_dot_is_valid(installed: Installed, write: Write) -> None:
    g = write("radar.yaml", RADAR)
    r = installed.run("graph", str(g), "--dot")
    assert r.returncode == 0, r.stderr
    nodes, edges = _dot_edges_by_regex(r.stdout)
    assert nodes == {"sim", "pairer", "doppler", "panoramic", "speckle", "slam", "tracker", "eval"}
    assert len(edges) == 14
    assert [(a, b) for a, b, dashed in edges if dashed] == [("slam", "panoramic")]
    # the default output (no option) is the same DOT text
    assert installed.run("graph", str(g)).stdout == r.stdout


def test_dot_parses_with_pydot(installed: Installed, write: Write, capsys: pytest.CaptureFixture[str]) -> None:
    pydot = pytest.importorskip("pydot")
    code, out, err = installed.main("graph", str(write("radar.yaml", RADAR)), capsys=capsys)
    assert code == 0, err
    with warnings.catch_warnings():  # pydot on a recent pyparsing warns about its own API use
        warnings.simplefilter("ignore")
        (graph,) = pydot.graph_from_dot_data(out)
    names = {n.get_name().strip('"') for n in graph.get_nodes()} - {"node", "edge"}
    assert len(names) == 8
    ends = {(e.get_source(), e.get_destination()) for e in graph.get_edges()}
    assert ('"slam":o0:e', '"panoramic":i3:w') in ends  # record ports: slam.pose -> panoramic.pose
    assert ('"sim":o3:e', '"eval":i1:w') in ends  # sim.gps -> eval.truth


def test_dot_escapes_record_characters(installed: Installed, write: Write, capsys: pytest.CaptureFixture[str]) -> None:
    g = write("odd.yaml", "name: odd\ncomponents:\n  'a<b>': {type: clitest.Ticker}\n"
              "  'c|d': {type: clitest.Printer, params: {label: x}}\nconnections: ['a<b>.tick -> c|d.x']\n")
    code, out, err = installed.main("graph", str(g), capsys=capsys)
    assert code == 0, err
    assert r'a\<b\>\nclitest.Ticker' in out and r'c\|d\nclitest.Printer' in out


def test_png(installed: Installed, write: Write, tmp_path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.image

    png = tmp_path / "radar.png"
    r = installed.run("graph", str(write("radar.yaml", RADAR)), "--png", str(png))
    assert r.returncode == 0, r.stderr
    assert r.stdout == ""  # --png alone prints no DOT
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = matplotlib.image.imread(png)
    h, w = img.shape[:2]
    assert w > 1.5 * h > 600  # left to right: wider than tall
    assert img[..., :3].std() > 0.05  # something is drawn


def test_png_and_dot_together_in_process(installed: Installed, write: Write, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    png = tmp_path / "small.png"
    g = write("small.yaml", "components:\n  t: {type: clitest.Ticker}\n  p: {type: clitest.Printer, "
              "params: {label: a}}\n  q: {type: clitest.Gain}\nconnections: [t.tick -> q.x, q.y -> p.x, "
              "'q.y -> q.bias [delay]']\n")
    code, out, err = installed.main("graph", str(g), "--png", str(png), "--dot", "--dpi", "80", capsys=capsys)
    assert code == 0, err
    assert out.startswith('digraph "small" {')
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_png_into_a_missing_directory(installed: Installed, write: Write, tmp_path: Path) -> None:
    r = installed.run("graph", str(write("radar.yaml", RADAR)), "--png", str(tmp_path / "no" / "g.png"))
    assert r.returncode == 1 and "no directory" in r.stderr and "Traceback" not in r.stderr


def test_png_without_matplotlib_names_the_extra(installed: Installed, write: Write, tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """The core install has no matplotlib: --png says which extra brings it, and writes nothing."""
    import sys

    monkeypatch.setitem(sys.modules, "matplotlib", None)  # `import matplotlib` raises ModuleNotFoundError
    png = tmp_path / "g.png"
    code, out, err = installed.main("graph", str(write("radar.yaml", RADAR)), "--png", str(png), capsys=capsys)
    assert code == 1 and out == "" and not png.exists()
    assert "--png draws with matplotlib, which is not installed: pip install 'impala-flow[plot]'" in err


def test_graph_of_an_invalid_file_exits_2(installed: Installed, write: Write) -> None:
    r = installed.run("graph", str(write("bad.yaml", RADAR.replace("sim.gps", "sim.gsp"))))
    assert r.returncode == 2
    assert re.search(r"bad\.yaml:\d+:\d+: .*has no output 'gsp' \(did you mean 'gps'\?\)", r.stderr)
