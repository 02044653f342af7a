"""Entry point of the SLAM plugin (``slam = "impala_slam.plugin"``).

Layout: docs/plugins.md, "Layout of a plugin" (``<algorithm>/component.py`` + ``core.py``);
components are registered by where they live (``module:Class``), imported when a graph uses them,
so loading the plugin stays cheap.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl, require

#: the libraries of this plugin's extra (pip install 'impala-flow[slam]'), checked before any hook runs
REQUIRES = ("scipy", "cv2", "filterpy", "gtsam", "numba")


@hookimpl
def impala_flow_register(registry: Any) -> None:
    require(*REQUIRES)
    for where in ("rslam.component:RSlam", "dead_reckoning.component:DeadReckoning",
                  "odometry.component:DistortionOdometry", "fmt.component:FmtRegistration",
                  "ekf_slam.component:EkfSlam", "posegraph.component:PoseGraph", "kissicp.component:KissIcp"):
        registry.add_component(f"{__package__}.{where}")  # imported when a graph uses it
