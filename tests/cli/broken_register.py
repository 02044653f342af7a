"""A plugin whose registration hook raises (for the plugin-failure tests)."""

from typing import Any

from impala_flow.plugins import hookimpl


@hookimpl
def impala_flow_register(registry: Any) -> None:
    raise RuntimeError("this plugin is broken on purpose")
