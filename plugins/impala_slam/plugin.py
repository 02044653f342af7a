"""Entry point of the SLAM plugin (``slam = "impala_slam.plugin"``).

Layout (docs/plugins.md, "Layout of a plugin"): one subpackage per algorithm,
``<algorithm>/component.py`` (the Component: ports, parameters, sample handling) and
``<algorithm>/core.py`` (the algorithm, no engine import beyond ``impala_flow.msgs`` and
``impala_msgs``); code several algorithms share in a module at the plugin's top; every
``__init__.py`` empty. Component modules are imported inside the hooks, so loading the plugin
(e.g. to build the command line) imports no OpenCV, GTSAM, SciPy or matplotlib.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl, require

#: the libraries of this plugin's extra (pip install 'impala-flow[slam]'), checked before any hook runs
REQUIRES = ("scipy", "cv2", "filterpy", "gtsam")


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
