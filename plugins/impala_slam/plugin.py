"""Entry point of the SLAM plugin (``slam = "impala_slam.plugin"``).

Layout: docs/plugins.md, "Layout of a plugin" (``<algorithm>/component.py`` + ``core.py``);
component modules are imported inside the hooks, so loading the plugin stays cheap.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl, require

#: the libraries of this plugin's extra (pip install 'impala-flow[slam]'), checked before any hook runs
REQUIRES = ("scipy", "cv2", "filterpy", "gtsam", "numba")


@hookimpl
def impala_flow_register(registry: Any) -> None:
    require(*REQUIRES)
    from .dead_reckoning.component import DeadReckoning
    from .ekf_slam.component import EkfSlam
    from .fmt.component import FmtRegistration
    from .kissicp.component import KissIcp
    from .odometry.component import DistortionOdometry
    from .posegraph.component import PoseGraph
    from .rslam.component import RSlam

    registry.add_component(RSlam)
    registry.add_component(DeadReckoning)
    registry.add_component(DistortionOdometry)
    registry.add_component(FmtRegistration)
    registry.add_component(EkfSlam)
    registry.add_component(PoseGraph)
    registry.add_component(KissIcp)
