"""Entry point of the SLAM plugin (``slam = "impala_slam.plugin"``)."""

from impala_flow.plugins import hookimpl

from .dead_reckoning import DeadReckoning
from .rslam import RSlam


@hookimpl
def impala_flow_register(registry):  # type: ignore[no-untyped-def]
    registry.add_component(RSlam)
    registry.add_component(DeadReckoning)
