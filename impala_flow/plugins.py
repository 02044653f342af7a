"""Plugin discovery: a pluggy manager built per run (never at import time).

Plugins come from the ``impala_flow`` entry-point group, built-in and third-party alike.
``IMPALA_FLOW_DISABLE_PLUGINS=radar,foo`` (comma-separated names) blocks plugins.
"""

from __future__ import annotations

import os
from typing import Any

import pluggy

from . import hookspecs
from .hookspecs import PROJECT, hookimpl
from .registry import PluginInfo, RegistrationError, Registry

__all__ = ["hookimpl", "make_plugin_manager", "load_registry", "DISABLE_ENV"]

DISABLE_ENV = "IMPALA_FLOW_DISABLE_PLUGINS"


def blocked_plugins() -> set[str]:
    return {n.strip() for n in os.environ.get(DISABLE_ENV, "").split(",") if n.strip()}


def make_plugin_manager(extra: dict[str, Any] | None = None, entrypoints: bool = True) -> pluggy.PluginManager:
    """A fresh manager with the installed plugins (minus the blocked) and ``extra`` ones."""
    pm = pluggy.PluginManager(PROJECT)
    pm.add_hookspecs(hookspecs)
    blocked = blocked_plugins()
    for name in blocked:
        pm.set_blocked(name)
    if entrypoints:
        try:
            pm.load_setuptools_entrypoints(PROJECT)  # skips blocked names
        except Exception as e:
            raise RegistrationError(f"a plugin of the '{PROJECT}' entry point group failed to load: "
                                    f"{type(e).__name__}: {e}") from e
    for name, obj in (extra or {}).items():
        if name not in blocked:
            pm.register(obj, name=name)
    return pm


def load_registry(pm: pluggy.PluginManager | None = None, extra: dict[str, Any] | None = None) -> Registry:
    """Call every plugin's ``impala_flow_register`` with a registry that knows the caller."""
    pm = pm or make_plugin_manager(extra)
    reg = Registry()
    versions = {pm.get_name(p): d.version for p, d in pm.list_plugin_distinfo()}
    for impl in reversed(pm.hook.impala_flow_register.get_hookimpls()):
        name = impl.plugin_name
        module = getattr(impl.plugin, "__name__", type(impl.plugin).__name__)
        info = PluginInfo(name=name, version=versions.get(name, ""), module=module)
        reg.plugins[name] = info
        reg._current = info
        try:
            impl.function(registry=reg)
        finally:
            reg._current = None
    reg.plugin_manager = pm  # type: ignore[attr-defined]
    return reg
