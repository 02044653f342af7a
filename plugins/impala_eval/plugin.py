"""Entry point of the evaluation plugin (``eval = "impala_eval.plugin"``)."""

from impala_flow.plugins import hookimpl

from .evaluator import TrajectoryEvaluator


@hookimpl
def impala_flow_register(registry):  # type: ignore[no-untyped-def]
    registry.add_component(TrajectoryEvaluator)
