"""Plugins: a real third-party package installed with pip, discovered through its entry
point, listed by ``impala-flow plugins``, run in YAML graphs; blocking by environment
variable; duplicate names; a plugin manager built per run, never at import time.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import json
import os
import subprocess
import sys
import textwrap
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from impala_flow._registry import RegistrationError
from impala_flow._session import Session
from impala_flow._spec import GraphError
from impala_flow.msgs import message
from impala_flow.plugins import DISABLE_ENV, hookimpl, load_registry, make_plugin_manager
from impala_flow.testing import CollectingSink, plugin_of

if TYPE_CHECKING:
    from conftest import ExamplePlugin  # the fixture's value (tests/conftest.py)

pytestmark = pytest.mark.usefixtures("example_plugin")

EXAMPLE_TYPES = ["example.Counter", "example.CsvWriter", "example.MovingAverage", "example.Threshold"]

# counter (10 Hz, 0, 1, 2, ...) -> moving average (window 4) -> threshold, whose level
# comes from a slow counter (5, 15, 25 at 0.05 s, 1.05 s, 2.05 s: never at a counter time)
GRAPH = """\
name: example-chain
variables: {out: out}
clock: {mode: replay, speed: max}
components:
  counter: {type: example.Counter, params: {rate: 10.0, count: 30}}
  level: {type: example.Counter, params: {rate: 1.0, count: 3, first: 5, step: 10, t0_ns: 50000000}}
  avg: {type: example.MovingAverage, params: {window: 4}}
  high: {type: example.Threshold, params: {default_level: 0.5}}
  mean_csv: {type: example.CsvWriter, params: {path: "${out}/mean.csv"}}
  above_csv: {type: example.CsvWriter, params: {path: "${out}/above.csv"}}
connections:
  - counter.value -> avg.x
  - avg.mean -> high.x
  - level.value -> high.level
  - avg.mean -> mean_csv.x
  - high.above -> above_csv.x
"""


def expected_chain(window: int = 4) -> tuple[list[int], list[float], list[bool]]:
    """The chain's outputs computed here, without the engine: (times ns, means, above)."""
    times = [k * 100_000_000 for k in range(30)]
    values = list(range(30))
    means = [float(Fraction(sum(values[max(0, k - window + 1): k + 1]), k + 1 - max(0, k - window + 1)))
             for k in range(30)]
    level_times, level_values = [50_000_000, 1_050_000_000, 2_050_000_000], [5, 15, 25]

    def level_at(t: int) -> float:
        known = [v for tl, v in zip(level_times, level_values, strict=True) if tl <= t]
        return known[-1] if known else 0.5

    above = [m > level_at(t) for t, m in zip(times, means, strict=True)]
    return times, means, above


def read_csv(path: Path) -> list[tuple[int, str]]:
    lines = path.read_text(encoding="utf-8").splitlines()
    assert lines[0] == "t_ns,value"
    return [(int(t), v) for t, v in (line.split(",") for line in lines[1:])]


def cli_command() -> list[str]:
    """The ``impala-flow`` console script of this environment (``python -m impala_flow`` if absent)."""
    script = Path(sys.executable).parent / "impala-flow"
    return [str(script)] if script.exists() else [sys.executable, "-m", "impala_flow"]


def cli(*args: str, env: dict[str, str] | None = None, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    full_env = {k: v for k, v in os.environ.items() if k != DISABLE_ENV}
    full_env.update(env or {})
    return subprocess.run([*cli_command(), *args], capture_output=True, text=True, env=full_env, cwd=cwd,
                          timeout=120, stdin=subprocess.DEVNULL)


# --- the package is installed and discovered -------------------------------------------

def test_installed_as_a_distribution(example_plugin: ExamplePlugin) -> None:
    dist = importlib.metadata.distribution(example_plugin.dist)
    assert dist.version == example_plugin.version
    eps = [ep for ep in dist.entry_points if ep.group == "impala_flow"]
    assert [(ep.name, ep.value) for ep in eps] == [("example", "impala_flow_example.plugin")]
    assert any(r.startswith("impala-flow") for r in dist.requires or [])
    # the module imported is the installed copy, not the sources under tests/
    mod = importlib.import_module(example_plugin.module)
    assert "plugin_example" not in Path(mod.__file__ or "").parts, (mod.__file__, example_plugin.how)


def test_discovered_in_process(example_plugin: ExamplePlugin) -> None:
    registry = load_registry()
    info = registry.plugins["example"]
    assert info.version == example_plugin.version
    assert info.module == "impala_flow_example.plugin"
    assert sorted(info.components) == EXAMPLE_TYPES
    assert all(registry.owner[name] == "example" for name in EXAMPLE_TYPES)
    assert registry.components["example.Counter"].__module__ == "impala_flow_example.components"


def test_plugins_command_lists_it(example_plugin: ExamplePlugin) -> None:
    r = cli("plugins")
    assert r.returncode == 0, r.stderr
    out = r.stdout
    assert "example" in out and example_plugin.version in out
    for name in EXAMPLE_TYPES:
        assert name in out
    # ports and parameters are part of the listing
    for word in ("value", "rate", "window", "mean", "above", "default_level"):
        assert word in out, f"'{word}' missing from `impala-flow plugins`:\n{out}"
    r = cli("plugins", "--json")
    assert r.returncode == 0, r.stderr
    (plugin,) = [p for p in json.loads(r.stdout)["plugins"] if p["name"] == "example"]
    assert plugin["version"] == example_plugin.version and plugin["module"] == example_plugin.module
    comps = {c["type"]: c for c in plugin["components"]}
    assert sorted(comps) == EXAMPLE_TYPES
    avg = comps["example.MovingAverage"]
    assert [(i["name"], i["policy"]) for i in avg["inputs"]] == [("x", "reactive")]
    assert [o["name"] for o in avg["outputs"]] == ["mean"]
    assert [(p["name"], p["default"], p["ge"]) for p in avg["params"]] == [("window", 4, 1)]
    level = {i["name"]: i for i in comps["example.Threshold"]["inputs"]}["level"]
    assert level["policy"] == "sampling" and level["required"] is False


def test_example_package_own_tests_pass_against_the_installed_package(example_plugin: ExamplePlugin,
                                                                      tmp_path: Path) -> None:
    r = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(example_plugin.source / "tests")],
        capture_output=True, text=True, cwd=tmp_path, timeout=300, stdin=subprocess.DEVNULL,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert " passed" in r.stdout and "failed" not in r.stdout


# --- a YAML graph of its components runs -----------------------------------------------

def test_graph_runs_with_the_command_line(tmp_path: Path) -> None:
    graph = tmp_path / "chain.yaml"
    graph.write_text(GRAPH, encoding="utf-8")
    out = tmp_path / "out"
    r = cli("run", str(graph), "--var", f"out={out}", "--summary-json", str(tmp_path / "summary.json"),
            "--no-progress", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    times, means, above = expected_chain()
    assert read_csv(out / "mean.csv") == [(t, repr(m)) for t, m in zip(times, means, strict=True)]
    assert read_csv(out / "above.csv") == [(t, repr(a)) for t, a in zip(times, above, strict=True)]
    summary = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))
    lost = {port: {k: n for k, n in stats.items() if k in ("dropped", "unmatched", "unconsumed") and n}
            for port, stats in summary["inputs"].items()}
    assert not any(lost.values()), lost
    assert summary["processed"]["avg"] == summary["processed"]["high"] == 30
    assert summary["extra"]["mean_csv"] == {"rows": 30}
    crossings = sum(a != b for a, b in zip(above, above[1:], strict=False))
    assert summary["extra"]["high"] == {"crossings": crossings}
    assert "no sample dropped" in r.stderr  # the run summary


def test_set_overrides_a_plugin_parameter(tmp_path: Path) -> None:
    graph = tmp_path / "chain.yaml"
    graph.write_text(GRAPH, encoding="utf-8")
    r = cli("run", str(graph), "--var", f"out={tmp_path}", "--set", "avg.window=2", "--no-progress")
    assert r.returncode == 0, r.stderr
    times, means, _ = expected_chain(window=2)
    assert read_csv(tmp_path / "mean.csv") == [(t, repr(m)) for t, m in zip(times, means, strict=True)]


def test_graph_runs_in_a_session(tmp_path: Path) -> None:
    text = GRAPH + "  - avg.mean -> sink.mean\n  - high.above -> sink.above\n"
    sink = "  sink: {type: test.CollectingSink, params: {ports: [mean, above]}}\n"
    text = text.replace("connections:", sink + "connections:")
    session = Session(extra_plugins={"test": plugin_of(CollectingSink)})
    spec = session.load_text(text, variables={"out": str(tmp_path)})
    net = session.build(spec)
    summary = session.run(net)
    sink = net.components["sink"]
    assert isinstance(sink, CollectingSink)
    times, means, above = expected_chain()
    assert sink.times("mean") == times and sink.times("above") == times
    assert sink.values("mean") == means
    assert sink.values("above") == above
    assert summary.drops() == {} and not summary.interrupted and summary.error is None
    assert read_csv(tmp_path / "mean.csv") == [(t, repr(m)) for t, m in zip(times, means, strict=True)]


def test_closest_installed_names_for_a_typo() -> None:
    with pytest.raises(GraphError) as e:
        Session().load_text("components:\n  c: {type: example.Countr}\n", name="typo.yaml")
    assert "typo.yaml:2:" in str(e.value)
    assert "unknown type 'example.Countr'" in str(e.value)
    assert "closest installed: example.Counter" in str(e.value)


# --- blocking ----------------------------------------------------------------------------

def test_environment_variable_blocks_it_in_process(monkeypatch: pytest.MonkeyPatch) -> None:
    class Counter(CollectingSink):
        """An in-test component whose name is close to the blocked one."""

    monkeypatch.setenv(DISABLE_ENV, "example")
    session = Session(extra_plugins={"mine": plugin_of(Counter)})
    assert "example" not in session.registry.plugins
    assert not [n for n in session.registry.components if n.startswith("example.")]
    assert session.pm.is_blocked("example")
    with pytest.raises(GraphError) as e:
        session.load_text(GRAPH, name="chain.yaml")
    msg = str(e.value)
    assert "chain.yaml:5:" in msg and "component 'counter': unknown type 'example.Counter'" in msg
    assert "closest installed: mine.Counter" in msg
    # blocking takes a comma-separated list and applies to in-process plugins too
    monkeypatch.setenv(DISABLE_ENV, " mine , example")
    assert "mine" not in Session(extra_plugins={"mine": plugin_of(Counter)}).registry.plugins
    monkeypatch.delenv(DISABLE_ENV)
    assert "example" in Session().registry.plugins


def test_environment_variable_blocks_it_on_the_command_line(tmp_path: Path) -> None:
    graph = tmp_path / "chain.yaml"
    graph.write_text(GRAPH, encoding="utf-8")
    r = cli("validate", str(graph), env={DISABLE_ENV: "example"})
    assert r.returncode == 2, r.stdout + r.stderr  # invalid graph
    assert "unknown type 'example.Counter'" in r.stderr
    assert f"{graph}:5:" in r.stderr  # file:line:column of the offending type
    assert "Traceback" not in r.stderr
    r = cli("validate", str(graph))
    assert r.returncode == 0, r.stderr
    r = cli("plugins", env={DISABLE_ENV: "example"})
    assert r.returncode == 0, r.stderr
    assert "example.Counter" not in r.stdout


# --- duplicate names -----------------------------------------------------------------------

@message("test.Reading")
class Reading:
    value: float


class _RegistersReading:
    """An in-test plugin registering the message type ``test.Reading`` and a codec ``csv``."""

    def __init__(self, codec: bool = False) -> None:
        self.codec = codec

    @hookimpl
    def impala_flow_register(self, registry) -> None:  # type: ignore[no-untyped-def]
        if self.codec:
            registry.add_codec("csv", object())
        else:
            registry.add_type(Reading)


def test_same_type_from_two_plugins_is_an_error_naming_both() -> None:
    with pytest.raises(RegistrationError) as e:
        Session(extra_plugins={"alpha": _RegistersReading(), "beta": _RegistersReading()})
    assert "'test.Reading'" in str(e.value)
    assert "'alpha'" in str(e.value) and "'beta'" in str(e.value)


def test_same_codec_from_two_plugins_is_an_error_naming_both() -> None:
    with pytest.raises(RegistrationError) as e:
        load_registry(extra={"alpha": _RegistersReading(codec=True), "beta": _RegistersReading(codec=True)})
    assert "csv" in str(e.value) and "'alpha'" in str(e.value) and "'beta'" in str(e.value)


def test_plugin_claiming_a_builtin_message_type_is_an_error() -> None:
    from impala_flow.msgs import Pose2D

    class Claims:
        @hookimpl
        def impala_flow_register(self, registry) -> None:  # type: ignore[no-untyped-def]
            registry.add_type(Pose2D)

    with pytest.raises(RegistrationError, match=r"'impala\.Pose2D'.*'impala_flow' and 'claims'"):
        load_registry(extra={"claims": Claims()})


def test_same_class_under_two_plugins_gets_two_names() -> None:
    registry = load_registry(extra={"one": plugin_of(CollectingSink), "two": plugin_of(CollectingSink)})
    assert {"one.CollectingSink", "two.CollectingSink"} <= set(registry.components)


def test_plugin_name_taken_twice_is_an_error_naming_both() -> None:
    with pytest.raises(RegistrationError) as e:
        Session(extra_plugins={"example": plugin_of(CollectingSink)})
    assert "impala_flow_example.plugin" in str(e.value)


# --- the plugin manager is built per run, never at import --------------------------------

def test_each_session_builds_its_own_manager_and_registry() -> None:
    first = Session(extra_plugins={"only_first": plugin_of(CollectingSink)})
    second = Session()
    assert first.pm is not second.pm and first.registry is not second.registry
    assert "only_first.CollectingSink" in first.registry.components
    assert "only_first.CollectingSink" not in second.registry.components
    assert "only_first" not in second.registry.plugins
    assert "example.Counter" in first.registry.components and "example.Counter" in second.registry.components
    assert make_plugin_manager() is not make_plugin_manager()


def test_importing_the_engine_loads_no_plugin() -> None:
    code = textwrap.dedent("""\
        import json, sys
        import pluggy
        built = []
        init = pluggy.PluginManager.__init__
        def spy(self, *a, **k):
            built.append(a)
            init(self, *a, **k)
        pluggy.PluginManager.__init__ = spy
        import impala_flow, impala_flow.plugins, impala_flow._session, impala_flow.testing, impala_flow.cli
        loaded = sorted(m for m in sys.modules
                        if m.split(".")[0] in {"impala_flow_example", "impala_radar", "impala_view",
                                               "impala_slam", "impala_tracking", "impala_eval", "impala_sweep",
                                               "impala_ros2"})
        at_import = len(built)
        from impala_flow._session import Session
        Session()
        print(json.dumps({"managers_at_import": at_import, "plugins_at_import": loaded,
                          "after_session": "impala_flow_example.plugin" in sys.modules}))
    """)
    env = {k: v for k, v in os.environ.items() if k != DISABLE_ENV}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120,
                       stdin=subprocess.DEVNULL)
    assert r.returncode == 0, r.stderr
    facts = json.loads(r.stdout)
    assert facts == {"managers_at_import": 0, "plugins_at_import": [], "after_session": True}
