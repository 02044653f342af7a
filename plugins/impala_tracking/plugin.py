"""Entry point of the tracking plugin (``tracking = "impala_tracking.plugin"``).

Layout: docs/plugins.md, "Layout of a plugin" (``<algorithm>/component.py`` + ``core.py``);
components are registered by where they live (``module:Class``), imported when a graph uses them,
so loading the plugin stays cheap.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl, require

#: the libraries of this plugin's extra (pip install 'impala-flow[tracking]'), checked before any hook runs
REQUIRES = ("scipy", "filterpy")


@hookimpl
def impala_flow_register(registry: Any) -> None:
    require(*REQUIRES)
    from .types import MoverDetections

    registry.add_type(MoverDetections)
    for where in ("detector.component:MoverDetector", "tracker.component:Tracker"):
        registry.add_component(f"{__package__}.{where}")  # imported when a graph uses it
