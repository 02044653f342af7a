"""Entry point of the evaluation plugin (``eval = "impala_eval.plugin"``).

Layout: docs/plugins.md, "Layout of a plugin" (``<algorithm>/component.py`` + ``core.py``);
components are registered by where they live (``module:Class``), imported when a graph uses them,
so loading the plugin stays cheap.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl, require

#: the libraries of this plugin's extra (pip install 'impala-flow[eval]'), checked before any hook runs
REQUIRES = ("matplotlib", "motmetrics")


@hookimpl
def impala_flow_register(registry: Any) -> None:
    require(*REQUIRES)
    for where in ("evaluator.component:TrajectoryEvaluator", "tracking.component:TrackingEvaluator",
                  "comparison.component:TrajectoryComparison"):
        registry.add_component(f"{__package__}.{where}")  # imported when a graph uses it


@hookimpl
def impala_flow_add_commands(subparsers: Any) -> None:
    require(*REQUIRES)
    from .demo import add_demo_command

    add_demo_command(subparsers)
