"""Entry point of the SLAM plugin (``slam = "impala_slam.plugin"``).

Component modules are imported inside the hook, so loading the plugin stays cheap.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl


@hookimpl
def impala_flow_register(registry: Any) -> None:
    from .dead_reckoning import DeadReckoning
    from .ekf_slam import EkfSlam
    from .kissicp import KissIcp
    from .odometry import DistortionOdometry
    from .posegraph import PoseGraph
    from .registration import FmtRegistration
    from .rslam import RSlam

    registry.add_component(RSlam)
    registry.add_component(DeadReckoning)
    registry.add_component(DistortionOdometry)
    registry.add_component(FmtRegistration)
    registry.add_component(EkfSlam)
    registry.add_component(PoseGraph)
    registry.add_component(KissIcp)
