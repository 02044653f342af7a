"""Entry point of the evaluation plugin (``eval = "impala_eval.plugin"``).

Layout: docs/plugins.md, "Layout of a plugin" (``<algorithm>/component.py`` + ``core.py``);
component modules are imported inside the hooks, so loading the plugin stays cheap.
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
