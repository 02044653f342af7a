"""A broken third-party plugin is left out: the others load, commands work, it is listed
with its error and the hint to block it, and only graphs using its types fail (issue 11.5)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest

from impala_flow._session import Session
from impala_flow.plugins import hookimpl, load_registry
from impala_flow.testing import CollectingSink, plugin_of

from .conftest import Installed

Write = Callable[[str, str], Path]

GRAPH = """\
name: fine
components:
  src: {type: clitest.Ticker, params: {count: 3}}
  out: {type: clitest.Printer, params: {label: v}}
connections:
  - src.tick -> out.x
"""

USES_BROKEN = """\
name: needs-missing
components:
  src: {type: clitest.Ticker, params: {count: 3}}
  thing: {type: missing.Thing}
connections:
  - src.tick -> thing.x
"""

MISSING_ERR = "ModuleNotFoundError: No module named 'tests.cli.no_such_module'"


@pytest.fixture
def with_missing(installed: Installed) -> Installed:
    """clitest plus a plugin 'missing' whose module does not exist."""
    installed.add("impala-flow-missing", "1.0", {"missing": "tests.cli.no_such_module"})
    return installed


def test_plugins_lists_the_others_and_the_broken_one_with_its_error_and_hint(with_missing: Installed) -> None:
    r = with_missing.run("plugins")
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert f"missing 1.0  [tests.cli.no_such_module]  BROKEN: {MISSING_ERR}" in lines
    assert any("IMPALA_FLOW_DISABLE_PLUGINS=missing" in line for line in lines)
    assert any(line.startswith("clitest 0.3.1") for line in lines)  # the others are listed
    assert lines[-1].endswith(", 1 broken plugin left out")
    assert "Traceback" not in r.stderr


def test_plugins_json_has_the_broken_plugin(with_missing: Installed, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = with_missing.main("plugins", "--json", capsys=capsys)
    assert code == 0, err
    data = json.loads(out)
    assert data["broken"] == [{"name": "missing", "entry_point": "tests.cli.no_such_module", "version": "1.0",
                               "error": MISSING_ERR, "hint": "IMPALA_FLOW_DISABLE_PLUGINS=missing hides it",
                               # its own module is missing, not a library: no pip line
                               "missing": "", "install": ""}]
    assert "clitest" in {p["name"] for p in data["plugins"]}


def test_validate_and_run_of_an_unrelated_graph_work_with_a_warning(with_missing: Installed, write: Write) -> None:
    g = write("fine.yaml", GRAPH)
    r = with_missing.run("validate", str(g))
    assert r.returncode == 0, r.stderr
    assert "ok - graph 'fine'" in r.stdout
    warn = [line for line in r.stderr.splitlines() if "plugin 'missing'" in line]
    assert len(warn) == 1 and MISSING_ERR in warn[0] and "IMPALA_FLOW_DISABLE_PLUGINS=missing" in warn[0]
    r = with_missing.run("run", str(g), "--no-progress")
    assert r.returncode == 0, r.stderr


def test_a_graph_using_the_broken_plugins_types_fails(with_missing: Installed, write: Write) -> None:
    r = with_missing.run("validate", str(write("bad.yaml", USES_BROKEN)))
    assert r.returncode == 2
    assert "missing.Thing" in r.stderr and "Traceback" not in r.stderr
    # the reason is the broken plugin, not a typo: its error and the hint, no "closest installed"
    assert "comes from plugin 'missing', which failed to load" in r.stderr
    assert MISSING_ERR in r.stderr and "IMPALA_FLOW_DISABLE_PLUGINS=missing" in r.stderr
    assert "closest installed" not in r.stderr


def test_module_raising_at_import_keeps_the_plugin_commands(installed: Installed) -> None:
    (installed.site / "explodes_at_import.py").write_text(
        "raise ImportError('needs libfoo.so, not installed')\n", encoding="utf-8")
    installed.add("impala-flow-explodes", "2.0", {"explodes": "explodes_at_import"})
    r = installed.run("--help")
    assert r.returncode == 0, r.stderr
    assert "simulate" in r.stdout and "demo" in r.stdout  # commands of the other plugins
    r = installed.run("plugins", "--json")
    assert r.returncode == 0, r.stderr
    (b,) = json.loads(r.stdout)["broken"]
    assert b["name"] == "explodes" and b["error"] == "ImportError: needs libfoo.so, not installed"


def test_blocked_broken_plugin_is_silent(with_missing: Installed, write: Write) -> None:
    with_missing.env["IMPALA_FLOW_DISABLE_PLUGINS"] = "missing"
    r = with_missing.run("validate", str(write("fine.yaml", GRAPH)))
    assert r.returncode == 0 and "missing" not in r.stderr


def test_registration_failing_half_way_is_rolled_back() -> None:
    class HalfWay:
        @hookimpl
        def impala_flow_register(self, registry) -> None:  # type: ignore[no-untyped-def]
            registry.add_component(CollectingSink)
            raise RuntimeError("second half failed")

    reg = load_registry(extra={"half": HalfWay(), "good": plugin_of(CollectingSink)})
    assert "half.CollectingSink" not in reg.components and "half" not in reg.plugins
    assert "half.CollectingSink" not in reg.owner
    assert "good.CollectingSink" in reg.components
    assert reg.broken["half"].error == "RuntimeError: second half failed"
    assert reg.why_unknown("half.CollectingSink") == (
        "type 'half.CollectingSink' comes from plugin 'half', which failed to load: RuntimeError: second half "
        "failed (IMPALA_FLOW_DISABLE_PLUGINS=half hides it)")
    assert reg.why_unknown("good.Other") is None


def test_session_with_a_broken_registration_still_runs_graphs(caplog: pytest.LogCaptureFixture) -> None:
    class Broken:
        @hookimpl
        def impala_flow_register(self, registry) -> None:  # type: ignore[no-untyped-def]
            raise RuntimeError("broken on purpose")

    s = Session(extra_plugins={"brk": Broken(), "ok": plugin_of(CollectingSink)}, entrypoints=False)
    assert "ok.CollectingSink" in s.registry.components and set(s.registry.broken) == {"brk"}
    assert [r.getMessage() for r in caplog.records if "brk" in r.getMessage()] == [
        "plugin 'brk' (Broken) failed to load: RuntimeError: broken on purpose; "
        "it is left out (IMPALA_FLOW_DISABLE_PLUGINS=brk hides it)"]
