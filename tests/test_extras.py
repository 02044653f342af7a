"""Install what you use (issue 25.3), checked on the source: every third-party module a package
imports is brought by what installs it. The engine and the message packages need only the core
``dependencies``; a plugin needs the core plus its extra, named like its entry point. A library
the engine uses in one optional place (``graph --png``) is imported inside that function, so the
core install runs without it. The install itself is proven by ``.ci/core-install``.
"""

from __future__ import annotations

import ast
import importlib
import re
import sys
import tomllib
from functools import cache
from importlib.metadata import packages_distributions
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
DIST = PROJECT["name"]
PLUGINS = PROJECT["entry-points"]["impala_flow"]          # entry point name -> "package.module"
MESSAGES = PROJECT["entry-points"]["impala_flow.messages"]  # message packages: core only
OURS = {"impala_flow"} | {v.split(".")[0].split(":")[0] for v in [*PLUGINS.values(), *MESSAGES.values()]}

#: engine imports outside the core, each inside the one function that needs it: module -> extra
ENGINE_OPTIONAL = {"matplotlib": "plot", "pytest": "test"}
#: engine modules allowed to import an optional library at their top: none
ENGINE_TOP_LEVEL_PENDING: set[str] = set()
#: a library an extra names beside the one that depends on it: checked through that one
TRANSITIVE = {"protobuf": "foxglove-schemas-protobuf", "distributed": "dask"}
#: the peer baselines (slam.KissIcp) come with the `peers` extra, imported by their component only
PEERS = "peers"


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _req_name(req: str) -> str:
    m = re.match(r"\s*([A-Za-z0-9][A-Za-z0-9._-]*)(?:\[([^\]]*)\])?", req)
    assert m, req
    return _norm(m.group(1))


def _expand(reqs: list[str]) -> set[str]:
    """Normalized distribution names of ``reqs``, our own extras (``impala-flow[a,b]``) expanded."""
    out: set[str] = set()
    for req in reqs:
        m = re.match(r"\s*([A-Za-z0-9][A-Za-z0-9._-]*)\[([^\]]*)\]", req)
        if m and _norm(m.group(1)) == _norm(DIST):
            for extra in m.group(2).split(","):
                out |= _expand(PROJECT["optional-dependencies"][extra.strip()])
        else:
            out.add(_req_name(req))
    return out


CORE = _expand(PROJECT["dependencies"])
EXTRAS = {name: _expand(reqs) for name, reqs in PROJECT["optional-dependencies"].items()}


def _package_dir(package: str) -> Path:
    return ROOT / package if (ROOT / package).is_dir() else ROOT / "plugins" / package


def _runs_at_import(stmt: ast.stmt) -> bool:
    """A module-level if block (not ``if TYPE_CHECKING:``) or try block (not guarded by ``except
    ImportError``): its imports run at import time and fail without the library."""
    if isinstance(stmt, ast.If):
        return "TYPE_CHECKING" not in ast.unparse(stmt.test)
    if isinstance(stmt, ast.Try):
        return not any(h.type is not None and re.search(r"ImportError|ModuleNotFoundError", ast.unparse(h.type))
                       for h in stmt.handlers)
    return False


def third_party_imports(package: str) -> dict[str, list[tuple[str, bool]]]:
    """Top-level third-party module -> [(file, imported at module level)] over ``package``'s source."""
    out: dict[str, list[tuple[str, bool]]] = {}
    base = _package_dir(package)
    for path in sorted(base.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        top_level = {id(n) for n in tree.body} | {id(n) for stmt in tree.body if _runs_at_import(stmt)
                                                  for n in ast.walk(stmt)}
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                if top in sys.stdlib_module_names or top in OURS or top == "__future__":
                    continue
                out.setdefault(top, []).append((str(path.relative_to(ROOT)), id(node) in top_level))
    return out


@cache
def _installed() -> dict[str, list[str]]:
    return packages_distributions()


def providers(module: str) -> set[str]:
    """The installed distributions providing ``module`` (this test runs where everything is installed)."""
    dists = {_norm(d) for d in _installed().get(module, [])}
    assert dists, f"no installed distribution provides '{module}': cannot check who brings it"
    return dists


def test_every_plugin_has_an_extra_named_like_its_entry_point() -> None:
    assert set(PLUGINS) <= set(EXTRAS), f"plugins without an extra: {sorted(set(PLUGINS) - set(EXTRAS))}"
    assert _expand(PROJECT["optional-dependencies"]["all"]) >= set().union(*(EXTRAS[p] for p in PLUGINS))
    assert EXTRAS["test"] >= EXTRAS["all"] | EXTRAS[PEERS]  # the README's test command sets up everything


def test_the_core_is_small_and_brings_no_chain_library() -> None:
    heavy = {"gtsam", "dask", "distributed", "opencv-python", "opencv-python-headless", "foxglove-sdk", "motmetrics",
             "filterpy", "matplotlib", "scipy", "protobuf", "pillow"}
    assert not CORE & heavy, sorted(CORE & heavy)
    assert {"numpy", "pyyaml", "mcap", "pluggy", "networkx"} <= CORE


@pytest.mark.parametrize("plugin", sorted(PLUGINS))
def test_a_plugin_imports_only_the_core_and_its_extra(plugin: str) -> None:
    package = PLUGINS[plugin].split(".")[0].split(":")[0]
    allowed = CORE | EXTRAS[plugin] | EXTRAS[PEERS]
    missing = {m: files[0][0] for m, files in third_party_imports(package).items() if not providers(m) & allowed}
    assert not missing, f"plugin '{plugin}' imports what neither the core nor [{plugin}] brings: {missing}"


@pytest.mark.parametrize("package", sorted(v.split(".")[0].split(":")[0] for v in MESSAGES.values()))
def test_a_message_package_needs_only_the_core(package: str) -> None:
    outside = {m: f[0][0] for m, f in third_party_imports(package).items() if not providers(m) & CORE}
    assert not outside, f"message package {package} imports outside the core: {outside}"


def test_the_engine_needs_only_the_core_at_import_time() -> None:
    for module, files in third_party_imports("impala_flow").items():
        if providers(module) & CORE:
            continue
        assert module in ENGINE_OPTIONAL, f"the engine imports {module} ({files[0][0]}), which the core lacks"
        extra = ENGINE_OPTIONAL[module]
        assert providers(module) & EXTRAS[extra], f"{module}: the extra [{extra}] does not bring it"
        eager = {f for f, top in files if top} - ENGINE_TOP_LEVEL_PENDING
        assert not eager, f"{module} is imported at the top of {sorted(eager)}: the core install could not import it"


@pytest.mark.parametrize("plugin", sorted(PLUGINS))
def test_what_a_plugin_requires_up_front_is_what_its_extra_brings(plugin: str) -> None:
    """A plugin's ``REQUIRES`` (checked by ``impala_flow.plugins.require`` before its hooks run)
    and its extra in pyproject.toml are two lists of one thing: every module it requires comes
    with its extra, and every library of its extra is required up front (one listed module per
    distribution is enough)."""
    module = importlib.import_module(PLUGINS[plugin].split(":")[0])
    required = getattr(module, "REQUIRES", None)
    assert required is not None, f"{PLUGINS[plugin]} declares no REQUIRES"
    brought = set().union(*(providers(m) for m in required)) if required else set()
    assert brought <= EXTRAS[plugin] | CORE, f"{plugin}: REQUIRES {required} brings {sorted(brought - EXTRAS[plugin])}"
    # every library the extra names is checked up front, directly or through the library that
    # depends on it (TRANSITIVE: protobuf comes with foxglove-schemas-protobuf, distributed with dask)
    named = {_norm(_req_name(r)) for r in PROJECT["optional-dependencies"][plugin]}
    unchecked = {n for n in named - brought if TRANSITIVE.get(n) not in brought}
    assert not unchecked, f"{plugin}: its extra brings {sorted(unchecked)}, which REQUIRES does not check"
