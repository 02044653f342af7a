"""Entry point of the evaluation plugin (``eval = "impala_eval.plugin"``)."""

from typing import Any

from impala_flow.plugins import hookimpl

from .evaluator import TrajectoryEvaluator


@hookimpl
def impala_flow_register(registry: Any) -> None:
    registry.add_component(TrajectoryEvaluator)


@hookimpl
def impala_flow_add_commands(subparsers: Any, registry: Any) -> None:
    from .demo import add_demo_command

    add_demo_command(subparsers)
