"""The ``pip install`` line that brings a plugin's missing library.

A plugin whose import or registration fails with ``ModuleNotFoundError`` for a module that is
not part of the plugin itself lacks an optional dependency. The distribution that provides the
plugin's entry point names its extras (``Provides-Extra``) and their requirements
(``Requires-Dist: gtsam>=4.2; extra == "slam"``); the hint names the extra that brings the
module: an extra whose requirement is the module (``gtsam``) or the installed distribution
that provides it (:func:`importlib.metadata.packages_distributions`), else the extra named
like the plugin. Built-in and third-party plugins get the same:
``plugin 'slam' needs gtsam: pip install 'impala-flow[slam]'``.
"""

from __future__ import annotations

import re
from importlib.metadata import Distribution, packages_distributions

__all__ = ["missing_module", "install_line"]

# Requires-Dist is parsed by hand: `packaging` is not a dependency of the engine
_NAME = re.compile(r"\s*([A-Za-z0-9][A-Za-z0-9._-]*)")
_EXTRA = re.compile(r"""\bextra\s*==\s*["']([^"']+)["']""")


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "_", name).lower()


def missing_module(error: BaseException, own_module: str) -> str:
    """The top-level module ``error`` says is missing, if it is not ``own_module``'s package, else ''."""
    if not isinstance(error, ModuleNotFoundError) or not error.name:
        return ""
    top = error.name.split(".", 1)[0]
    return "" if top == own_module.split(":", 1)[0].split(".", 1)[0] else top


def _extras(dist: Distribution) -> dict[str, list[str]]:
    """Extra (as declared) -> the normalized names it requires (a self-reference ``pkg[a,b]`` excluded)."""
    own = _norm(dist.metadata.get("Name") or "")
    declared = {_norm(e): e for e in dist.metadata.get_all("Provides-Extra") or []}
    out: dict[str, list[str]] = {e: [] for e in declared.values()}
    for req in dist.requires or []:
        name, extra = _NAME.match(req), _EXTRA.search(req)
        if name and extra and _norm(extra.group(1)) in declared and _norm(name.group(1)) != own:
            out[declared[_norm(extra.group(1))]].append(_norm(name.group(1)))
    return out


def install_line(dist: Distribution | None, plugin: str, module: str) -> str:
    """``pip install '<dist>[<extra>]'`` for the extra of ``dist`` that brings ``module``, or ''."""
    if dist is None or not module:
        return ""
    extras = _extras(dist)
    providers = {_norm(module)} | {_norm(d) for d in packages_distributions().get(module, [])}
    named = [e for e in extras if _norm(e) == _norm(plugin)]
    bringing = sorted((e for e, reqs in extras.items() if providers & set(reqs)),
                      key=lambda e: (e not in named, len(extras[e]), e))
    extra = (bringing or named or [""])[0]
    return f"pip install '{dist.metadata['Name']}[{extra}]'" if extra else ""
