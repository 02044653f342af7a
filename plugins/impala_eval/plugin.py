"""Entry point of the evaluation plugin (``eval = "impala_eval.plugin"``).

Component and command modules are imported inside the hooks, so loading the plugin (e.g.
to build the command line) stays cheap.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl


@hookimpl
def impala_flow_register(registry: Any) -> None:
    from .comparison import TrajectoryComparison
    from .evaluator import TrajectoryEvaluator
    from .tracking import TrackingEvaluator

    registry.add_component(TrajectoryEvaluator)
    registry.add_component(TrackingEvaluator)
    registry.add_component(TrajectoryComparison)


@hookimpl
def impala_flow_add_commands(subparsers: Any) -> None:
    from .demo import add_demo_command

    add_demo_command(subparsers)
