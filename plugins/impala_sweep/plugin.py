"""Entry point of the sweep plugin: the ``impala-flow sweep`` command (its register hook adds no
component: it lists the plugin, or says which library of the ``sweep`` extra is missing)."""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl, require

#: the libraries of this plugin's extra (pip install 'impala-flow[sweep]'), checked before any hook runs
REQUIRES = ("dask", "distributed", "matplotlib")


@hookimpl
def impala_flow_add_commands(subparsers: Any) -> None:
    require(*REQUIRES)
    from .command import add_parser

    add_parser(subparsers)


@hookimpl
def impala_flow_register(registry: Any) -> None:
    require(*REQUIRES)
