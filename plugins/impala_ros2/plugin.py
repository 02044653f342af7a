"""Entry point of the ROS 2 plugin: the ``ros2`` output format (standard ROS 2 messages, CDR).

Nothing ROS is imported here: the writer imports mcap-ros2-support when a recording asks for it.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl, require

#: the libraries of this plugin's extra (pip install 'impala-flow[ros2]'), checked before any hook runs
REQUIRES = ("mcap_ros2",)


def _ros2_writer() -> Any:
    from .write import Ros2Writer

    return Ros2Writer()


@hookimpl
def impala_flow_register(registry: Any) -> None:
    require(*REQUIRES)
    registry.add_foreign_writer("ros2", _ros2_writer)
