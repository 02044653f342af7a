"""A component type registered by where it lives (``registry.add_component("pkg.module:Class")``):
its name is known at once, its module imported only when the type is looked up (a graph uses it,
a command describes it); a module failing then leaves its plugin broken, as a failing
registration does, and only graphs using the type fail, saying why."""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
import textwrap
import uuid
from pathlib import Path

import pytest

from impala_flow._registry import RegistrationError, Registry
from impala_flow._session import Session
from impala_flow._spec import GraphError
from impala_flow.plugins import DISABLE_ENV, hookimpl, load_registry
from impala_flow.testing import CollectingSink, ScriptedSource, plugin_of

GRAPH = """\
name: lazy
components:
  src: {type: eager.ScriptedSource, params: {ports: [out]}}
  sink: {type: lazy.LazySink}
connections:
  - src.out -> sink.x
"""


def lazy_plugin(*targets: str) -> object:
    """A plugin registering ``targets`` ("module:Class") by where they live."""

    class _Plugin:
        @staticmethod
        @hookimpl
        def impala_flow_register(registry) -> None:  # type: ignore[no-untyped-def]
            for t in targets:
                registry.add_component(t)

    return _Plugin()


@pytest.fixture
def lazy_module(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    """The name of a fresh module (never imported yet) defining the component ``LazySink``."""
    name = f"lazy_components_{uuid.uuid4().hex}"
    (tmp_path / f"{name}.py").write_text(textwrap.dedent("""\
        from impala_flow.testing import CollectingSink


        class LazySink(CollectingSink):
            \"\"\"A sink defined in a module the registry imports only when the type is used.\"\"\"
        """))
    monkeypatch.syspath_prepend(str(tmp_path))
    return name


def session(*targets: str) -> Session:
    return Session(extra_plugins={"eager": plugin_of(ScriptedSource), "lazy": lazy_plugin(*targets)},
                   entrypoints=False)


def test_the_module_is_imported_when_the_type_is_looked_up(lazy_module: str) -> None:
    s = session(f"{lazy_module}:LazySink")
    reg = s.registry
    assert "lazy.LazySink" in reg.components and sorted(reg.components) == ["eager.ScriptedSource",
                                                                            "io.Recorder", "io.Replayer",
                                                                            "lazy.LazySink"]
    assert reg.plugins["lazy"].components == ["lazy.LazySink"] and reg.owner["lazy.LazySink"] == "lazy"
    assert lazy_module not in sys.modules  # registered, listed, not imported
    assert reg.components.where("lazy.LazySink") == f"{lazy_module}:LazySink"
    cls = reg.components["lazy.LazySink"]
    assert lazy_module in sys.modules and cls is sys.modules[lazy_module].LazySink
    assert cls.type_name == "lazy.LazySink" and issubclass(cls, CollectingSink)
    assert reg.components.where("lazy.LazySink") == f"{lazy_module}:LazySink"


def test_a_graph_runs_with_a_lazily_registered_type(lazy_module: str) -> None:
    s = session(f"{lazy_module}:LazySink")
    spec = s.load_text(GRAPH, overrides=[])
    net = s.build(spec)
    net.components["src"].script = [(10, "out", 1.5), (20, "out", 2.5)]
    s.run(net)
    sink = net.components["sink"]
    assert type(sink).__name__ == "LazySink" and sink.values() == [1.5, 2.5] and sink.times() == [10, 20]


def test_a_class_a_command_builds_itself_gets_its_registered_name(lazy_module: str) -> None:
    reg = session(f"{lazy_module}:LazySink").registry
    __import__(lazy_module)
    cls = sys.modules[lazy_module].LazySink
    assert cls.__dict__.get("type_name") is None  # nothing has looked it up yet
    assert reg.name_of(cls) == "lazy.LazySink" == cls.type_name
    assert reg.name_of(ScriptedSource) == "eager.ScriptedSource"


def test_a_module_failing_to_import_leaves_its_plugin_broken(caplog: pytest.LogCaptureFixture) -> None:
    missing = f"no_such_module_{uuid.uuid4().hex}"
    with caplog.at_level(logging.WARNING, logger="impala_flow.plugins"):
        s = session(f"{missing}:Thing")
        assert "lazy.Thing" in s.registry.components and not s.registry.broken  # not imported yet
        with pytest.raises(GraphError) as e:
            s.load_text(GRAPH.replace("lazy.LazySink", "lazy.Thing"))
    reg = s.registry
    error = f"ModuleNotFoundError: No module named '{missing}'"
    assert f"type 'lazy.Thing' comes from plugin 'lazy', which failed to load: {error} " \
           f"(IMPALA_FLOW_DISABLE_PLUGINS=lazy hides it)" in str(e.value)
    assert "lazy.Thing" not in reg.components and "lazy.Thing" not in reg.owner
    assert reg.plugins["lazy"].components == []
    b = reg.broken["lazy"]
    assert (b.name, b.target, b.error) == ("lazy", f"{missing}:Thing", error)
    assert [r.getMessage() for r in caplog.records] == [
        f"plugin 'lazy' ({missing}:Thing) failed to load: {error}; its type lazy.Thing is left out "
        "(IMPALA_FLOW_DISABLE_PLUGINS=lazy hides it)"]
    assert reg.components.get("eager.ScriptedSource") is ScriptedSource  # the others still work


def test_a_target_that_is_no_component_leaves_its_plugin_broken() -> None:
    reg = session("impala_flow.testing:plugin_of").registry
    assert reg.components.get("lazy.plugin_of") is None
    assert reg.broken["lazy"].error.startswith("RegistrationError: impala_flow.testing:plugin_of is not a "
                                               "Component subclass (<function plugin_of")


@pytest.mark.parametrize("bad", ["no_colon", "module:", ":Class", "module:not an identifier", 3])
def test_a_malformed_target_is_refused_at_registration(bad: object) -> None:
    with pytest.raises(RegistrationError, match="add_component expects a Component subclass"):
        Registry().add_component(bad)  # type: ignore[arg-type]
    reg = load_registry(extra={"bad": lazy_plugin(bad)})  # type: ignore[arg-type]
    assert "bad" not in reg.plugins and reg.broken["bad"].error.startswith("RegistrationError: add_component")


def test_the_installed_plugins_import_no_component_module_until_used() -> None:
    code = textwrap.dedent("""\
        import json, sys
        from impala_flow._session import Session
        s = Session()
        def loaded():
            return sorted(m for m in sys.modules if m.endswith(".component") or m.endswith(".bridge"))
        before = loaded()
        cls = s.registry.components["slam.RSlam"]
        print(json.dumps({"before": before, "after": loaded(), "type_name": cls.type_name,
                          "scipy": "scipy" in sys.modules, "n": len(s.registry.components)}))
        """)
    env = {k: v for k, v in os.environ.items() if k != DISABLE_ENV}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120,
                       stdin=subprocess.DEVNULL)
    assert r.returncode == 0, r.stderr
    facts = json.loads(r.stdout)
    assert facts["before"] == [] and facts["scipy"] is False
    assert facts["after"] == ["impala_slam.rslam.component"] and facts["type_name"] == "slam.RSlam"
    assert facts["n"] >= 25  # every in-tree type listed without importing any


def test_listing_and_schema_import_every_type_and_list_a_failing_one_as_broken(lazy_module: str) -> None:
    from impala_flow._schema import graph_schema
    from impala_flow.cli._plugins import describe_plugins

    missing = f"no_such_module_{uuid.uuid4().hex}"
    s = session(f"{lazy_module}:LazySink", f"{missing}:Thing")
    data = describe_plugins(s.registry)
    lazy = next(p for p in data["plugins"] if p["name"] == "lazy")
    assert [c["type"] for c in lazy["components"]] == ["lazy.LazySink"]
    assert lazy["components"][0]["inputs"][0]["name"] == "x"  # described from the imported class
    assert [(b["name"], b["entry_point"], b["error"]) for b in data["broken"]] == [
        ("lazy", f"{missing}:Thing", f"ModuleNotFoundError: No module named '{missing}'")]
    schema = graph_schema(s.registry)
    types = schema["$defs"]["component"]["else"]["properties"]["type"]["enum"]
    assert "lazy.LazySink" in types and "lazy.Thing" not in types and "params:lazy.LazySink" in schema["$defs"]
