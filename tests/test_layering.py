"""Layering: the engine never imports a plugin or a message package, and a plugin never imports
another plugin (the shared message packages, ``impala_msgs``, are what plugins share).

Checked twice: by import-linter (the contract in pyproject.toml, on the import graph of
the installed packages) and by a scan of the source files' syntax trees, which also sees
imports inside functions and ``TYPE_CHECKING`` blocks and ``importlib.import_module``
calls with a literal name.
"""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ENGINE = ROOT / "impala_flow"
PLUGINS_DIR = ROOT / "plugins"
EXAMPLE = ROOT / "tests" / "plugin_example" / "impala_flow_example"

#: the built-in plugins of DESIGN.md, whether or not they have landed yet, plus whatever
#: package sits in plugins/, plus the third-party example
#: message packages (the ``impala_flow.messages`` entry point group): every plugin may import them
MESSAGE_PACKAGES = {"impala_msgs"}
PLUGIN_PACKAGES = sorted(
    ({"impala_radar", "impala_slam", "impala_tracking", "impala_eval", "impala_view", "impala_flow_example"}
     | {p.parent.name for p in PLUGINS_DIR.glob("*/__init__.py")}) - MESSAGE_PACKAGES
)
#: third-party libraries only the view plugin imports (the engine mirrors nothing itself)
VIEW_ONLY = {"foxglove", "foxglove_schemas_protobuf", "google"}


def imported_modules(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import in ``path``, relative ones resolved."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = path.relative_to(_root_of(path)).parts[:-1]  # ("impala_flow", "cli") for impala_flow/cli/x.py
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(package[: len(package) - node.level + 1])
                mod = ".".join([*base, node.module] if node.module else base)
            else:
                mod = node.module or ""
            found.append((node.lineno, mod))  # its top-level package is all the checks need
        elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant) \
                and isinstance(node.args[0].value, str):
            fn = node.func
            name = fn.attr if isinstance(fn, ast.Attribute) else fn.id if isinstance(fn, ast.Name) else ""
            if name in ("import_module", "__import__"):
                found.append((node.lineno, node.args[0].value))
    return found


def _root_of(path: Path) -> Path:
    """The folder on sys.path that ``path``'s top-level package sits in."""
    p = path.parent
    while (p / "__init__.py").exists():
        p = p.parent
    return p


def _top(module: str) -> str:
    return module.split(".")[0]


def _python_files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*.py") if "__pycache__" not in p.parts and "build" not in p.parts)


def test_the_scan_sees_imports(tmp_path: Path) -> None:  # guards the scanner itself
    pkg = tmp_path / "impala_flow" / "sub"
    pkg.mkdir(parents=True)
    (pkg.parent / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("from . import x\n")
    (pkg / "x.py").write_text(
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    import impala_flow.io\n"
        "def f():\n    from ..msgs import Pose2D\n    import importlib\n"
        "    return importlib.import_module('impala_radar.simulator')\n"
    )
    assert imported_modules(pkg / "__init__.py") == [(1, "impala_flow.sub")]
    assert [(line, m) for line, m in imported_modules(pkg / "x.py") if _top(m) != "typing"] == [
        (3, "impala_flow.io"), (5, "impala_flow.msgs"), (6, "importlib"), (7, "impala_radar.simulator"),
    ]
    mods = {m for _, m in imported_modules(ENGINE / "plugins.py")}
    assert {"pluggy", "impala_flow.hookspecs", "impala_flow._registry"} <= mods
    mods = {m for _, m in imported_modules(ENGINE / "cli" / "__init__.py")}
    assert "impala_flow.plugins" in mods  # a function-level, relative import


def test_engine_imports_no_plugin() -> None:
    files = _python_files(ENGINE)
    assert len(files) > 10
    bad = [f"{f.relative_to(ROOT)}:{line}: imports {mod}"
           for f in files for line, mod in imported_modules(f)
           if _top(mod) in PLUGIN_PACKAGES or _top(mod) in MESSAGE_PACKAGES or _top(mod) in VIEW_ONLY]
    assert not bad, "the engine must not import a plugin, a domain message package or Foxglove:\n" + "\n".join(bad)


def test_only_the_view_plugin_imports_foxglove_and_protobuf() -> None:
    files = [f for p in PLUGINS_DIR.iterdir() if p.name != "impala_view" for f in _python_files(p)]
    assert len(files) > 10
    bad = [f"{f.relative_to(ROOT)}:{line}: imports {mod}"
           for f in files for line, mod in imported_modules(f) if _top(mod) in VIEW_ONLY]
    assert not bad, "only impala_view imports foxglove and protobuf:\n" + "\n".join(bad)


BUILTIN_PRESENT = [p for p in PLUGIN_PACKAGES if (PLUGINS_DIR / p).is_dir()]


@pytest.mark.parametrize("package", [*BUILTIN_PRESENT, "impala_flow_example"])
def test_plugin_imports_no_other_plugin(package: str) -> None:
    folder = EXAMPLE if package == "impala_flow_example" else PLUGINS_DIR / package
    bad = [f"{f.relative_to(ROOT)}:{line}: imports {mod}"
           for f in _python_files(folder) for line, mod in imported_modules(f)
           if _top(mod) in PLUGIN_PACKAGES and _top(mod) != package]
    assert not bad, (f"{package} must not import another plugin (shared types go to impala_msgs):\n"
                     + "\n".join(bad))


def test_example_plugin_uses_only_the_engine_and_the_standard_library() -> None:
    third_party = {_top(mod) for f in _python_files(EXAMPLE) for _, mod in imported_modules(f)}
    third_party -= set(sys.stdlib_module_names) | {"__future__", "impala_flow", "impala_flow_example"}
    assert not third_party


def test_import_linter_contract_covers_every_builtin_plugin() -> None:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["importlinter"]
    present = {p for p in BUILTIN_PRESENT if (PLUGINS_DIR / p / "__init__.py").exists()}  # importable packages
    assert "impala_flow" in config["root_packages"]
    assert present <= set(config["root_packages"])
    forbidden = [c for c in config["contracts"] if c["type"] == "forbidden" and "impala_flow" in c["source_modules"]]
    assert forbidden, "no import-linter contract keeps the engine from importing plugins"
    assert present <= {m for c in forbidden for m in c["forbidden_modules"]}


def test_lint_imports() -> None:
    exe = Path(sys.executable).parent / "lint-imports"
    cmd = [str(exe)] if exe.exists() else [shutil.which("lint-imports") or "lint-imports"]
    r = subprocess.run([*cmd, "--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=300,
                       stdin=subprocess.DEVNULL)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "0 broken" in r.stdout, r.stdout


def _private_names_taken(path: Path) -> list[tuple[int, str]]:
    """(line, 'module.name') of every ``_name`` (not a module, not a dunder) that ``path`` imports
    from another module: a private name used across modules should be public in its module."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = path.relative_to(_root_of(path)).parts[:-1]
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level:
            base = list(package[: len(package) - node.level + 1])
            mod = ".".join([*base, node.module] if node.module else base)
        else:
            mod = node.module or ""
        folder = _root_of(path).joinpath(*mod.split("."))
        for alias in node.names:
            name = alias.name
            if not name.startswith("_") or name.startswith("__"):
                continue
            if (folder / f"{name}.py").exists() or (folder / name / "__init__.py").exists():
                continue  # a (private) module of that package, imported inside it
            found.append((node.lineno, f"{mod}.{name}"))
    return found


def test_no_private_name_is_taken_from_another_module() -> None:
    files = _python_files(ENGINE) + [f for p in BUILTIN_PRESENT for f in _python_files(PLUGINS_DIR / p)]
    bad = [f"{f.relative_to(ROOT)}:{line}: imports {name}" for f in files for line, name in _private_names_taken(f)]
    assert not bad, "make these names public in their module (or move the code):\n" + "\n".join(bad)
