"""Entry point of the evaluation plugin (``eval = "impala_eval.plugin"``).

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

#: the libraries of this plugin's extra (pip install 'impala-flow[eval]'), checked before any hook runs
REQUIRES = ("matplotlib", "motmetrics")


@hookimpl
def impala_flow_register(registry: Any) -> None:
    require(*REQUIRES)
    from .comparison.component import TrajectoryComparison
    from .evaluator.component import TrajectoryEvaluator
    from .tracking.component import TrackingEvaluator

    registry.add_component(TrajectoryEvaluator)
    registry.add_component(TrackingEvaluator)
    registry.add_component(TrajectoryComparison)


@hookimpl
def impala_flow_add_commands(subparsers: Any) -> None:
    require(*REQUIRES)
    from .demo import add_demo_command

    add_demo_command(subparsers)
