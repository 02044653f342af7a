"""Entry point of the io plugin: registers io.Recorder, io.Replayer, io.FoxgloveBridge and the
``view`` command.

Component modules are imported inside the hook, so loading the plugin (e.g. to build the
command line) stays cheap.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl


@hookimpl
def impala_flow_register(registry: Any) -> None:
    from .bridge import FoxgloveBridge
    from .recorder import Recorder
    from .replayer import Replayer

    registry.add_component(Recorder)
    registry.add_component(Replayer)
    registry.add_component(FoxgloveBridge)


@hookimpl
def impala_flow_add_commands(subparsers: Any) -> None:
    from .commands import add_commands

    add_commands(subparsers)
