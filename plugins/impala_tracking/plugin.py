"""Entry point of the tracking plugin (``tracking = "impala_tracking.plugin"``).

Component modules are imported inside the hook, so loading the plugin stays cheap.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl


@hookimpl
def impala_flow_register(registry: Any) -> None:
    from .detector import MoverDetector
    from .tracker import Tracker
    from .types import MoverDetections

    registry.add_type(MoverDetections)
    registry.add_component(MoverDetector)
    registry.add_component(Tracker)
