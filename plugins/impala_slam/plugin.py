"""Entry point of the SLAM plugin (``slam = "impala_slam.plugin"``).

Component modules are imported inside the hook, so loading the plugin stays cheap.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl


@hookimpl
def impala_flow_register(registry: Any) -> None:
    from .dead_reckoning import DeadReckoning
    from .odometry import DistortionOdometry
    from .rslam import RSlam

    registry.add_component(RSlam)
    registry.add_component(DeadReckoning)
    registry.add_component(DistortionOdometry)
