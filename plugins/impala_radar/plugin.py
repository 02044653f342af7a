"""Entry point of the radar plugin: radar sources, front-end components, CLI commands."""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl


@hookimpl
def impala_flow_register(registry: Any) -> None:
    from .sources import OxfordScans, Simulator

    registry.add_component(Simulator)
    registry.add_component(OxfordScans)


@hookimpl
def impala_flow_add_commands(subparsers: Any, registry: Any) -> None:
    from .commands import add_commands

    add_commands(subparsers)
