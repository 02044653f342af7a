"""A plugin whose extra is missing is listed with the ``pip install`` line that brings it
(issue 25.3): the distribution providing its entry point declares the extra, and the engine
finds it the same way for a third-party distribution as for impala-flow itself."""

from __future__ import annotations

import json
from collections.abc import Callable
from importlib.metadata import PathDistribution
from pathlib import Path

import pytest

from impala_flow._extras import install_line, missing_module

from .conftest import Installed

Write = Callable[[str, str], Path]

#: a library nobody installs
LIB = "impala_no_such_lib"
#: the distribution "impala-chain": its plugin "chain" needs LIB, brought by the extra "chain"
CHAIN_META = ("Provides-Extra: chain\nProvides-Extra: docs\n"
              'Requires-Dist: impala-no-such-lib>=1.0; extra == "chain"\n'
              'Requires-Dist: mkdocs>=1.6; extra == "docs"\n')
#: registers fine until it needs the library (imported inside the hook, as a lazy plugin does)
REGISTERS_LATE = f"""\
from impala_flow.plugins import hookimpl


@hookimpl
def impala_flow_register(registry):
    import {LIB}.core  # noqa: F401
"""
#: fails at import (the plugin module imports the library at its top)
IMPORTS_EARLY = f"import {LIB}\n"
#: declares its extra's libraries up front with impala_flow.plugins.require (as the built-in plugins do):
#: its components would import the library only when a graph runs them
REQUIRES_UP_FRONT = f"""\
from impala_flow.plugins import hookimpl, require


@hookimpl
def impala_flow_register(registry):
    require("json", "{LIB}.core")
"""

USES_CHAIN = """\
name: needs-chain
components:
  src: {type: clitest.Ticker, params: {count: 3}}
  thing: {type: chain.Thing}
connections:
  - src.tick -> thing.x
"""

LINE = "pip install 'impala-chain[chain]'"


@pytest.fixture(params=["register", "import", "require"])
def with_chain(request: pytest.FixtureRequest, installed: Installed) -> Installed:
    """clitest plus 'chain', whose library is missing (at registration, at import, or declared by require)."""
    code = {"register": REGISTERS_LATE, "import": IMPORTS_EARLY, "require": REQUIRES_UP_FRONT}[request.param]
    (installed.site / "chain_plugin.py").write_text(code, encoding="utf-8")
    installed.add("impala-chain", "1.2", {"chain": "chain_plugin"}, CHAIN_META)
    return installed


def test_plugins_lists_the_plugin_with_the_pip_line(with_chain: Installed) -> None:
    r = with_chain.run("plugins")
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert f"chain 1.2  [chain_plugin]  NEEDS {LIB}: {LINE}" in lines
    assert any(line.startswith("clitest 0.3.1") for line in lines)  # the others load
    assert lines[-1].endswith(", 1 broken plugin left out")
    assert "Traceback" not in r.stderr


def test_plugins_json_has_the_missing_library_and_the_line(with_chain: Installed) -> None:
    r = with_chain.run("plugins", "--json")
    assert r.returncode == 0, r.stderr
    (b,) = json.loads(r.stdout)["broken"]
    assert (b["name"], b["missing"], b["install"]) == ("chain", LIB, LINE)
    assert b["error"] == f"ModuleNotFoundError: No module named '{LIB}'"


def test_validate_of_a_graph_naming_its_component_shows_the_line(with_chain: Installed, write: Write) -> None:
    r = with_chain.run("validate", str(write("g.yaml", USES_CHAIN)))
    assert r.returncode == 2
    assert f"unknown component type chain.Thing: plugin 'chain' needs {LIB}: {LINE}" in r.stderr
    assert "closest installed" not in r.stderr and "Traceback" not in r.stderr


def test_the_warning_of_an_unrelated_graph_has_the_line(with_chain: Installed, write: Write) -> None:
    printer = "  out: {type: clitest.Printer, params: {label: v}}\n"
    graph = USES_CHAIN.replace("  thing: {type: chain.Thing}\n", printer).replace("thing.x", "out.x")
    r = with_chain.run("validate", str(write("fine.yaml", graph)))
    assert r.returncode == 0, r.stderr
    (warn,) = [line for line in r.stderr.splitlines() if "plugin 'chain'" in line]
    assert f"plugin 'chain' (chain_plugin) needs {LIB}: {LINE}; it is left out" in warn
    assert "IMPALA_FLOW_DISABLE_PLUGINS=chain" in warn


def test_a_plugin_whose_commands_need_the_library_keeps_the_others_commands(installed: Installed) -> None:
    (installed.site / "cmds_plugin.py").write_text(
        f"from impala_flow.plugins import hookimpl\n\n\n@hookimpl\ndef impala_flow_add_commands(subparsers):\n"
        f"    import {LIB}  # noqa: F401\n", encoding="utf-8")
    installed.add("impala-chain", "1.2", {"chain": "cmds_plugin"}, CHAIN_META)
    r = installed.run("--help")
    assert r.returncode == 0, r.stderr
    assert "simulate" in r.stdout and "demo" in r.stdout  # the commands of the other plugins
    (warn,) = [line for line in r.stderr.splitlines() if "plugin 'chain'" in line]
    assert f"plugin 'chain' (cmds_plugin) needs {LIB}: {LINE}; its commands are left out" in warn


def test_an_extra_whose_requirement_is_the_module_wins_over_the_plugin_name(installed: Installed) -> None:
    """The plugin 'thing' of 'impala-things' needs LIB, which its extra 'fast' brings (no extra 'thing')."""
    (installed.site / "thing_plugin.py").write_text(IMPORTS_EARLY, encoding="utf-8")
    installed.add("impala-things", "3.0", {"thing": "thing_plugin"},
                  'Provides-Extra: fast\nProvides-Extra: all\nRequires-Dist: impala-no-such-lib; extra == "fast"\n'
                  'Requires-Dist: impala-things[fast]; extra == "all"\nRequires-Dist: numpy; extra == "all"\n')
    r = installed.run("plugins")
    assert f"thing 3.0  [thing_plugin]  NEEDS {LIB}: pip install 'impala-things[fast]'" in r.stdout.splitlines()


def test_no_extra_brings_it_says_so_without_a_line(installed: Installed, write: Write) -> None:
    (installed.site / "bare_plugin.py").write_text(IMPORTS_EARLY, encoding="utf-8")
    installed.add("impala-bare", "0.1", {"bare": "bare_plugin"})
    r = installed.run("plugins")
    assert f"bare 0.1  [bare_plugin]  NEEDS {LIB}: not installed" in r.stdout.splitlines()
    r = installed.run("validate", str(write("g.yaml", USES_CHAIN.replace("chain.", "bare."))))
    assert r.returncode == 2
    assert f"unknown component type bare.Thing: plugin 'bare' needs {LIB}, which is not installed" in r.stderr


# --- the rules, on a distribution read from a dist-info folder -------------------------------
def _dist(tmp_path: Path, meta: str) -> PathDistribution:
    info = tmp_path / "impala_demo-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: impala-demo\nVersion: 1.0\n{meta}", encoding="utf-8")
    return PathDistribution(info)


def test_an_installed_module_maps_to_its_distribution(tmp_path: Path) -> None:
    """``yaml`` is PyYAML's module: an extra requiring PyYAML brings it (packages_distributions)."""
    dist = _dist(tmp_path, 'Provides-Extra: conf\nProvides-Extra: demo\nRequires-Dist: PyYAML>=6; extra == "conf"\n')
    assert install_line(dist, "demo", "yaml") == "pip install 'impala-demo[conf]'"
    assert install_line(dist, "demo", "cv2") == "pip install 'impala-demo[demo]'"  # else the plugin's name
    assert install_line(dist, "other", "cv2") == ""
    assert install_line(None, "demo", "cv2") == ""


def test_the_extra_named_like_the_plugin_wins_among_those_bringing_the_module(tmp_path: Path) -> None:
    dist = _dist(tmp_path, 'Provides-Extra: a\nProvides-Extra: my-plugin\nRequires-Dist: gtsam; extra == "a"\n'
                           'Requires-Dist: gtsam>=4.2; extra == "my-plugin"\n'
                           'Requires-Dist: scipy; extra == "my-plugin"\n')
    assert install_line(dist, "my_plugin", "gtsam") == "pip install 'impala-demo[my-plugin]'"
    assert install_line(dist, "other", "gtsam") == "pip install 'impala-demo[a]'"  # the smallest


def test_missing_module_is_a_library_outside_the_plugin() -> None:
    assert missing_module(ModuleNotFoundError("No module named 'gtsam'", name="gtsam"), "impala_slam.plugin") == "gtsam"
    assert missing_module(ModuleNotFoundError("x", name="cv2.ximgproc"), "impala_slam.plugin:x") == "cv2"
    assert missing_module(ModuleNotFoundError("x", name="chain_plugin"), "chain_plugin:obj") == ""
    assert missing_module(ModuleNotFoundError("x", name="impala_slam.fmt"), "impala_slam.plugin") == ""
    assert missing_module(ModuleNotFoundError("x"), "impala_slam.plugin") == ""
    assert missing_module(ImportError("libfoo.so"), "impala_slam.plugin") == ""
