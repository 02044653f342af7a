"""Plugin discovery: a pluggy manager built per run (never at import time).

Plugins come from the ``impala_flow`` entry-point group, built-in and third-party alike.
``IMPALA_FLOW_DISABLE_PLUGINS=radar,foo`` (comma-separated names) blocks plugins. The engine's
own components (``io``: io.Recorder, io.Replayer) are registered first, by the engine, in every
manager; they cannot be blocked, and an entry point claiming their name is left out as broken
(``IMPALA_FLOW_DISABLE_PLUGINS=io`` hides it).

A broken plugin (its module fails to import, or its ``impala_flow_register`` raises) never
takes the others down: it is left out (what it registered before failing is removed),
recorded in ``PluginManager.broken`` / ``Registry.broken`` with its one-line error, logged
once as a warning, and listed by ``impala-flow plugins``; only graphs using its types fail.
A plugin failing for a library its installation lacks (``ModuleNotFoundError`` for a module
outside the plugin) is listed with the ``pip install`` line of the extra that brings it
(:mod:`impala_flow._extras`: ``plugin 'slam' needs gtsam: pip install 'impala-flow[slam]'``).
Two plugins claiming one name remain an error of the installation
(:class:`~impala_flow._registry.NameConflictError`, naming both).
"""

from __future__ import annotations

import importlib.util
import logging
import os
from importlib.metadata import Distribution
from typing import Any

import pluggy

from . import _builtin as _engine_io
from . import hookspecs
from ._extras import install_line, missing_module
from ._registry import BrokenPlugin, MissionSource, NameConflictError, PluginInfo, Registry
from .hookspecs import PROJECT, hookimpl
from .io import set_plugin_loader

__all__ = ["hookimpl", "Registry", "MissionSource", "NameConflictError", "make_plugin_manager", "load_registry",
           "DISABLE_ENV", "PluginManager", "warn_broken", "add_commands", "require"]

DISABLE_ENV = "IMPALA_FLOW_DISABLE_PLUGINS"

log = logging.getLogger("impala_flow.plugins")


def require(*modules: str) -> None:
    """Raise ``ModuleNotFoundError`` naming the first of ``modules`` (top-level import names, e.g.
    ``"cv2"``, ``"gtsam"``; a dotted name imports its parent package) that is not installed.
    A plugin calls it first in its hooks with the libraries of its extra, so that without them
    it is listed as broken with the ``pip install`` line that brings them, instead of loading
    and failing later in a graph. Nothing is imported (:func:`importlib.util.find_spec`), so
    the check costs microseconds."""
    for m in modules:
        try:
            found = importlib.util.find_spec(m) is not None
        except ModuleNotFoundError as e:  # a dotted name whose parent package is missing: name the parent
            m, found = e.name or m, False
        if not found:
            raise ModuleNotFoundError(f"No module named '{m}'", name=m)


def _one_line(e: BaseException) -> str:
    msg = str(e).strip().splitlines()
    return f"{type(e).__name__}: {msg[0]}" if msg else type(e).__name__


def _broken(name: str, target: str, version: str, error: BaseException, dist: Distribution | None) -> BrokenPlugin:
    """The record of a plugin that failed with ``error``; a missing library comes with its pip line."""
    missing = missing_module(error, target)
    return BrokenPlugin(name, target, version, _one_line(error), missing,
                        install_line(dist, name, missing) if missing else "")


def blocked_plugins() -> set[str]:
    return {n.strip() for n in os.environ.get(DISABLE_ENV, "").split(",") if n.strip()}


class PluginManager(pluggy.PluginManager):
    """pluggy's manager, plus the distribution (``dists``) and its version of every entry-point
    plugin and the plugins that failed to import (``broken``)."""

    def __init__(self) -> None:
        super().__init__(PROJECT)
        self.versions: dict[str, str] = {}
        self.dists: dict[str, Distribution] = {}
        self.broken: dict[str, BrokenPlugin] = {}


def make_plugin_manager(extra: dict[str, Any] | None = None, entrypoints: bool = True) -> PluginManager:
    """A fresh manager with the engine's own components, the installed plugins (minus the
    blocked) and ``extra`` ones."""
    from ._version import __version__

    pm = PluginManager()
    pm.add_hookspecs(hookspecs)
    pm.register(_engine_io, name=_engine_io.NAME)  # the engine's own: never blocked
    pm.versions[_engine_io.NAME] = __version__
    asked = blocked_plugins()  # blocking 'io' hides only an entry point claiming the name
    blocked = asked - {_engine_io.NAME}
    for name in blocked:
        pm.set_blocked(name)
    if entrypoints:
        from importlib.metadata import entry_points

        for ep in sorted(entry_points(group=PROJECT), key=lambda e: e.name):
            if pm.is_blocked(ep.name):
                continue
            version = ep.dist.version if ep.dist else ""
            if ep.name == _engine_io.NAME:
                if ep.name not in asked and ep.name not in pm.broken:
                    pm.broken[ep.name] = BrokenPlugin(ep.name, ep.value, version, f"'{ep.name}' names the engine's "
                                                      "own components (io.Recorder, io.Replayer): stale installation?")
                continue
            if pm.get_plugin(ep.name) is not None or ep.name in pm.broken:
                raise NameConflictError(f"two installed plugins are named '{ep.name}' ({ep.value})")
            try:
                plugin = ep.load()
            except Exception as e:  # one broken plugin must not disable the others
                pm.broken[ep.name] = _broken(ep.name, ep.value, version, e, ep.dist)
                continue
            pm.register(plugin, name=ep.name)
            pm.versions[ep.name] = version
            if ep.dist is not None:
                pm.dists[ep.name] = ep.dist
    for name, obj in (extra or {}).items():
        if name in blocked:
            continue
        if pm.get_plugin(name) is not None:
            raise NameConflictError(f"two plugins are named '{name}': the installed "
                                    f"{getattr(pm.get_plugin(name), '__name__', name)} and {obj!r}")
        pm.register(obj, name=name)
    return pm


def warn_broken(registry: Registry) -> None:
    """Log one warning per broken plugin of ``registry``, with the hint to block it."""
    for b in registry.broken.values():
        log.warning("%s; it is left out (%s)", b.describe(), b.hint)


def add_commands(pm: PluginManager, subparsers: Any) -> None:
    """Call every plugin's ``impala_flow_add_commands``, one plugin at a time: a plugin whose hook
    raises (a library its installation lacks) is left out with one warning (and the ``pip
    install`` line), the other plugins keep their commands."""
    for impl in reversed(pm.hook.impala_flow_add_commands.get_hookimpls()):
        try:
            impl.function(**{a: subparsers for a in impl.argnames if a == "subparsers"})
        except Exception as e:  # one plugin's commands must not hide the others'
            name = impl.plugin_name
            module = getattr(impl.plugin, "__name__", type(impl.plugin).__name__)
            b = _broken(name, module, getattr(pm, "versions", {}).get(name, ""), e, getattr(pm, "dists", {}).get(name))
            log.warning("%s; its commands are left out (%s)",
                        b.describe().replace("failed to load", "failed to add its commands"), b.hint)


def load_registry(pm: PluginManager | None = None, extra: dict[str, Any] | None = None) -> Registry:
    """Call every plugin's ``impala_flow_register`` with a registry that knows the caller.

    A plugin whose hook raises (anything but a name conflict with another plugin) is left
    out and joins ``registry.broken`` with the plugins that failed to import
    (:func:`warn_broken` tells the user)."""
    pm = pm or make_plugin_manager(extra)
    reg = Registry()
    versions = getattr(pm, "versions", {})
    dists = getattr(pm, "dists", {})
    reg.broken.update(getattr(pm, "broken", {}))
    reg.broken_plugin = lambda name, target, e: _broken(name, target, versions.get(name, ""), e, dists.get(name))
    for impl in reversed(pm.hook.impala_flow_register.get_hookimpls()):
        name = impl.plugin_name
        module = getattr(impl.plugin, "__name__", type(impl.plugin).__name__)
        info = PluginInfo(name=name, version=versions.get(name, ""), module=module)
        reg.plugins[name] = info
        reg._current = info
        try:
            impl.function(registry=reg)
        except NameConflictError:
            raise
        except Exception as e:
            reg.forget(name)
            reg.broken[name] = _broken(name, module, info.version, e, dists.get(name))
        finally:
            reg._current = None
    reg.plugin_manager = pm  # type: ignore[attr-defined]
    return reg


# a recorder or replayer wired by hand (no graph, so no registry of its run) records with the
# installed plugins' types and mirrors, loaded here: io sits below this module and never imports it
set_plugin_loader(load_registry)
