"""The hooks a plugin implements. Every hook is prefixed ``impala_flow_``.

A plugin is a module (or object) registered under the ``impala_flow`` entry-point
group; the entry point's name is the plugin's name and the prefix of its types in YAML
(entry point ``radar`` -> ``radar.FuzzyPairer``)::

    [project.entry-points.impala_flow]
    mything = "mything.plugin"

    # mything/plugin.py
    from impala_flow.plugins import hookimpl

    @hookimpl
    def impala_flow_register(registry):
        registry.add_component(MyFilter)
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import pluggy

if TYPE_CHECKING:
    import argparse

    from ._registry import Registry

__all__ = ["PROJECT", "hookspec", "hookimpl", "impala_flow_register", "impala_flow_add_commands",
           "impala_flow_graph_loaded"]

PROJECT = "impala_flow"
hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


@hookspec
def impala_flow_register(registry: Registry) -> None:
    """Register this plugin's components, message types, codecs and mission sources on ``registry``.

    Called once per plugin per run, with a registry that knows which plugin is calling,
    so names are prefixed and duplicates are reported with both plugins named.

    Mission sources: a plugin that can make a mission recording (a simulator, a dataset
    importer) offers it with ``registry.add_mission_source(name, make, help)``, where
    ``make(session, scenario, path, *, seed=None, duration_s=None)`` writes the recording to
    ``path`` and raises with a one-line message when it cannot. Other plugins (the sweep)
    call it through ``session.registry.mission_sources[name]``, never through the plugin's
    command line; the radar plugin offers ``simulate``, the same code as its ``impala-flow
    simulate`` command, so both write the same bytes. (A registry method rather than a hook
    of its own: the source is tagged with its plugin, a name offered twice is reported with
    both plugins, and a plugin that fails to register leaves none behind.)
    """


@hookspec
def impala_flow_add_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add subcommands to the ``impala-flow`` command line.

    Each parser must set ``func=callable(args) -> int`` with ``set_defaults``. Called while
    the command line is parsed, before any registry exists: import what a command needs
    inside its function, and open a ``Session`` there when it needs the plugins.
    """


@hookspec
def impala_flow_graph_loaded(graph: Any) -> None:
    """Inspect (never replace) a validated graph before it runs, e.g. to log it."""
