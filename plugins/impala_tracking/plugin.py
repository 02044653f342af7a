"""Entry point of the tracking plugin (``tracking = "impala_tracking.plugin"``).

Layout: docs/plugins.md, "Layout of a plugin" (``<algorithm>/component.py`` + ``core.py``);
component modules are imported inside the hooks, so loading the plugin stays cheap.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl, require

#: the libraries of this plugin's extra (pip install 'impala-flow[tracking]'), checked before any hook runs
REQUIRES = ("scipy", "filterpy")


@hookimpl
def impala_flow_register(registry: Any) -> None:
    require(*REQUIRES)
    from .detector.component import MoverDetector
    from .tracker.component import Tracker
    from .types import MoverDetections

    registry.add_type(MoverDetections)
    registry.add_component(MoverDetector)
    registry.add_component(Tracker)
