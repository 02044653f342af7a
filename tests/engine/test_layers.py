"""Layers inside the engine: zero import circles, every engine module placed in the layers
contract, and the graph pipeline (load -> resolve -> validate -> build) run stage by stage
through the session a user's command opens.

The order of the layers itself is checked by import-linter (the ``layers`` contract in
pyproject.toml, run by tests/test_layering.py::test_lint_imports).
"""

from __future__ import annotations

import os
import textwrap
import tomllib
from pathlib import Path

import grimp
import networkx as nx
import pytest

from impala_flow import Component, Input, Output, Param, Source
from impala_flow._session import Session
from impala_flow._spec import GraphError
from impala_flow.testing import CollectingSink, plugin_of

ROOT = Path(__file__).resolve().parents[2]
CONFIG = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["importlinter"]

#: circles allowed to remain: none
PENDING_CIRCLES: set[frozenset[str]] = set()


def import_circles() -> list[set[str]]:
    """Strongly connected components (more than one module) of the import graph of every
    first-party package (import-linter's root packages). grimp counts every import,
    those inside functions and ``if TYPE_CHECKING:`` blocks included: a circle of type
    hints is a circle too."""
    graph = grimp.build_graph(*CONFIG["root_packages"], cache_dir=None)
    g = nx.DiGraph()
    for m in graph.modules:
        g.add_node(m)
        g.add_edges_from((m, d) for d in graph.find_modules_directly_imported_by(m))
    return [s for s in nx.strongly_connected_components(g) if len(s) > 1]


def test_no_import_circle_in_any_first_party_package():
    circles = [sorted(c) for c in import_circles() if frozenset(c) not in PENDING_CIRCLES]
    assert circles == []


def test_the_circle_finder_sees_a_circle(tmp_path, monkeypatch):  # guards the check above
    pkg = tmp_path / "circlepkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from . import b\n")
    (pkg / "b.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from . import a\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(CONFIG, "root_packages", ["circlepkg"])
    assert import_circles() == [{"circlepkg.a", "circlepkg.b"}]


def _engine_layers() -> list[set[str]]:
    contracts = [c for c in CONFIG["contracts"] if c["type"] == "layers" and c.get("containers") == ["impala_flow"]]
    assert len(contracts) == 1, "one import-linter layers contract for the engine (containers: impala_flow)"
    return [{name.strip() for name in layer.split("|")} for layer in contracts[0]["layers"]]


def test_layers_contract_places_every_engine_module():
    """A new engine module has to be given its layer (the contract ignores unlisted ones)."""
    placed = set().union(*_engine_layers())
    engine = ROOT / "impala_flow"
    modules = {p.stem for p in engine.glob("_*.py") if p.stem not in ("__init__", "__main__")}
    modules |= {"cli", "testing", "plugins", "hookspecs", "msgs", "io"}
    assert sorted(modules - placed) == []


def test_layers_contract_orders_the_graph_pipeline_and_the_executors():
    rank = {m: i for i, layer in enumerate(_engine_layers()) for m in layer}  # 0 is the top
    assert rank["_session"] < rank["_build"] < rank["_validate"] < rank["_resolve"] <= rank["_load"] < rank["_spec"]
    assert rank["_offline"] == rank["_realtime"] < rank["_lifecycle"] < rank["_network"] < rank["_component"]


# --- the pipeline, stage by stage, through the session -------------------------------------------

class Lines(Source):
    out = Output(str)
    path = Param(str, path="read", doc="text file, one line a sample")

    def generate(self):
        with open(self.path, encoding="utf-8") as f:
            for i, line in enumerate(f):
                yield i * 1000, "out", line.strip()


class Upper(Component):
    x = Input(str)
    y = Output(str)

    def process(self, t):
        self.y.emit(t, self.x.take().upper())


@pytest.fixture
def session():
    return Session(extra_plugins={"t": plugin_of(Lines, Upper, CollectingSink)})


def test_session_runs_the_stages_in_order(tmp_path, session, monkeypatch):
    (tmp_path / "graphs").mkdir()
    (tmp_path / "graphs" / "words.txt").write_text("a\nb\n")
    graph = tmp_path / "graphs" / "g.yaml"
    graph.write_text(textwrap.dedent("""\
        components:
          src: {type: t.Lines, params: {path: words.txt}}
          up: t.Upper
          sink: t.CollectingSink
        connections:
          - src.out -> up.x
          - up.y -> sink.x
    """))
    monkeypatch.chdir(tmp_path)
    spec, problems = session.read("graphs/g.yaml")  # load: YAML -> spec, paths as written
    assert problems == [] and spec.components["src"].params["path"] == "words.txt"
    assert session.resolve(spec) == []  # resolve: against the graph file's folder
    assert spec.components["src"].params["path"] == os.path.join("graphs", "words.txt")
    assert session.validate(spec) == []  # validate: against the installed components
    net = session.build(spec)  # build: the network an executor runs
    summary = session.run(net)
    assert net.components["sink"].values() == ["A", "B"] and summary.processed["up"] == 2
    # Session.load is the same stages in that order
    loaded = session.load("graphs/g.yaml")
    assert loaded.components["src"].params == spec.components["src"].params


def test_load_reports_every_stage_problem_at_once(tmp_path, session):
    graph = tmp_path / "g.yaml"
    graph.write_text(textwrap.dedent("""\
        components:
          src: {type: t.Lines, params: {path: missing.txt}}
          up: {type: t.Uper}
          sink: {type: t.CollectingSink, colour: red}
        connections:
          - src.out -> up.x
          - up.y -> sink.x
    """))
    spec, problems = session.read(graph)
    assert [p.message for p in problems] == [
        "unknown key 'colour' in component 'sink'; expected one of type, params, on_error, description, override, "
        "inputs"]
    with pytest.raises(GraphError) as e:
        session.load(graph)
    # load's problem first, then validate's, each located
    assert [str(p) for p in e.value.problems] == [
        str(problems[0]), f"{graph}:3:8: component 'up': unknown type 't.Uper' (closest installed: t.Upper)"]
