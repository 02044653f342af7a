"""The engine's own components, registered by the engine itself as plugin ``io`` (before the
installed plugins, and never blocked): io.Recorder and io.Replayer."""

from __future__ import annotations

from typing import Any

from .hookspecs import hookimpl

__all__ = ["impala_flow_register", "NAME"]

#: the plugin name the engine's recording components are registered under (YAML ``io.Recorder``)
NAME = "io"


@hookimpl
def impala_flow_register(registry: Any) -> None:
    from .io import Recorder, Replayer

    registry.add_component(Recorder)
    registry.add_component(Replayer)
