"""Entry point of the sweep plugin: the ``impala-flow sweep`` command."""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl


@hookimpl
def impala_flow_add_commands(subparsers: Any) -> None:
    from .command import add_parser

    add_parser(subparsers)
