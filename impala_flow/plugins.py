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

__all__ = ["hookimpl", "make_plugin_manager", "load_registry", "DISABLE_ENV", "PluginManager"]

DISABLE_ENV = "IMPALA_FLOW_DISABLE_PLUGINS"


def blocked_plugins() -> set[str]:
    return {n.strip() for n in os.environ.get(DISABLE_ENV, "").split(",") if n.strip()}


class PluginManager(pluggy.PluginManager):
    """pluggy's manager, plus the distribution version of every entry-point plugin."""

    def __init__(self) -> None:
        super().__init__(PROJECT)
        self.versions: dict[str, str] = {}


def make_plugin_manager(extra: dict[str, Any] | None = None, entrypoints: bool = True) -> PluginManager:
    """A fresh manager with the installed plugins (minus the blocked) and ``extra`` ones."""
    pm = PluginManager()
    pm.add_hookspecs(hookspecs)
    blocked = blocked_plugins()
    for name in blocked:
        pm.set_blocked(name)
    if entrypoints:
        from importlib.metadata import entry_points

        for ep in sorted(entry_points(group=PROJECT), key=lambda e: e.name):
            if pm.is_blocked(ep.name):
                continue
            if pm.get_plugin(ep.name) is not None:
                raise RegistrationError(f"two installed plugins are named '{ep.name}' ({ep.value})")
            try:
                plugin = ep.load()
            except Exception as e:
                raise RegistrationError(f"plugin '{ep.name}' ({ep.value}) failed to load: "
                                        f"{type(e).__name__}: {e}") from e
            pm.register(plugin, name=ep.name)
            pm.versions[ep.name] = ep.dist.version if ep.dist else ""
    for name, obj in (extra or {}).items():
        if name in blocked:
            continue
        if pm.get_plugin(name) is not None:
            raise RegistrationError(f"two plugins are named '{name}': the installed "
                                    f"{getattr(pm.get_plugin(name), '__name__', name)} and {obj!r}")
        pm.register(obj, name=name)
    return pm


def load_registry(pm: PluginManager | None = None, extra: dict[str, Any] | None = None) -> Registry:
    """Call every plugin's ``impala_flow_register`` with a registry that knows the caller."""
    pm = pm or make_plugin_manager(extra)
    reg = Registry()
    versions = getattr(pm, "versions", {})
    for impl in reversed(pm.hook.impala_flow_register.get_hookimpls()):
        name = impl.plugin_name
        module = getattr(impl.plugin, "__name__", type(impl.plugin).__name__)
        info = PluginInfo(name=name, version=versions.get(name, ""), module=module)
        reg.plugins[name] = info
        reg._current = info
        try:
            impl.function(registry=reg)
        except RegistrationError:
            raise
        except Exception as e:
            raise RegistrationError(f"plugin '{name}' failed to register: {type(e).__name__}: {e}") from e
        finally:
            reg._current = None
    reg.plugin_manager = pm  # type: ignore[attr-defined]
    return reg
