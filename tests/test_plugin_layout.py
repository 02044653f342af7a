"""The built-in plugins' layout (docs/plugins.md, "Layout of a plugin"): loading a plugin loads no
heavy library, every package ``__init__`` is empty, one subpackage per algorithm with its
``component.py``, and ``core.py`` modules free of the engine beyond ``impala_flow.msgs``."""

from __future__ import annotations

import ast
import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

PLUGINS = ("impala_radar", "impala_slam", "impala_tracking", "impala_eval")
#: libraries a component needs, never the plugin module discovery imports
HEAVY = ("cv2", "gtsam", "scipy", "matplotlib", "filterpy", "motmetrics", "numba")


def _root(plugin: str) -> Path:
    spec = importlib.util.find_spec(plugin)
    assert spec is not None and spec.submodule_search_locations, plugin
    return Path(next(iter(spec.submodule_search_locations)))


def _imports(path: Path) -> list[str]:
    """Modules a file imports (absolute, or relative with its leading dots), at any depth."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            out.append("." * node.level + (node.module or ""))
    return out


@pytest.mark.parametrize("plugin", PLUGINS)
def test_loading_the_plugin_module_imports_no_heavy_library(plugin: str) -> None:
    code = (f"import sys, {plugin}.plugin\n"
            f"print(','.join(m for m in {HEAVY!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"importing {plugin}.plugin loads {out.stdout.strip()}"


@pytest.mark.parametrize("plugin", PLUGINS)
def test_every_package_init_is_empty(plugin: str) -> None:
    inits = sorted(_root(plugin).rglob("__init__.py"))
    assert len(inits) > 1
    for init in inits:
        body = ast.parse(init.read_text(encoding="utf-8")).body
        docstring = body[:1] if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
            else []
        assert body == docstring, f"{init} holds more than a docstring"


@pytest.mark.parametrize("plugin", PLUGINS)
def test_one_subpackage_per_algorithm_with_component_and_core(plugin: str) -> None:
    root = _root(plugin)
    folders = sorted(p.parent for p in root.glob("*/__init__.py"))
    assert folders, plugin
    for folder in folders:
        assert (folder / "component.py").is_file(), f"{folder} has no component.py"
        core = folder / "core.py"
        if core.is_file():
            engine = [m for m in _imports(core) if m.startswith("impala_flow") and m != "impala_flow.msgs"
                      and not m.startswith("impala_flow.msgs.")]
            # `from impala_flow import msgs` is the message module too
            text = core.read_text(encoding="utf-8")
            engine = [m for m in engine if not (m == "impala_flow" and "from impala_flow import msgs\n" in text)]
            assert engine == [], f"{core} imports the engine: {engine}"
            assert not any(m.endswith("component") for m in _imports(core)), f"{core} imports a component module"


def test_plugin_modules_import_component_modules_only_inside_the_hooks() -> None:
    for plugin in PLUGINS:
        tree = ast.parse((_root(plugin) / "plugin.py").read_text(encoding="utf-8"))
        top = [n for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom))]
        names = [("." * n.level + (n.module or "")) if isinstance(n, ast.ImportFrom) else n.names[0].name for n in top]
        assert set(names) <= {"__future__", "typing", "impala_flow.plugins"}, (plugin, names)


def test_the_radar_plugin_has_no_shim_modules() -> None:
    root = _root("impala_radar")
    assert not (root / "navtech.py").exists()
    assert not (root / "sources.py").exists()
    assert not (root / "frontend").exists() and not (root / "sim").exists()
