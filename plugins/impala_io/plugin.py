"""Entry point of the io plugin: registers io.Recorder and io.Replayer.

Component modules are imported inside the hook, so loading the plugin (e.g. to build the
command line) stays cheap.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl


@hookimpl
def impala_flow_register(registry: Any) -> None:
    from .recorder import Recorder
    from .replayer import Replayer

    registry.add_component(Recorder)
    registry.add_component(Replayer)
