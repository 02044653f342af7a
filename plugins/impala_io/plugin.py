"""Entry point of the io plugin: registers io.Recorder and io.Replayer."""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl

from .recorder import Recorder
from .replayer import Replayer


@hookimpl
def impala_flow_register(registry: Any) -> None:
    registry.add_component(Recorder)
    registry.add_component(Replayer)
