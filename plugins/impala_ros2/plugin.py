"""Entry point of the ros2 plugin: adapters reading ROS 2 channels (rosbag2 MCAP files), the
``import ros2`` command, and the ``ros2`` output format (standard ROS 2 messages, CDR, beside or
instead of the native channels).

Nothing ROS is imported here: the adapters and the writer import mcap-ros2-support when used.
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
    from .read.adapters import register_adapters

    register_adapters(registry)
    registry.add_foreign_writer("ros2", _ros2_writer)


@hookimpl(trylast=True)  # after the plugin that may own `import` (radar): `ros2` joins its formats
def impala_flow_add_commands(subparsers: Any) -> None:
    require(*REQUIRES)
    from .command import add_import_ros2

    add_import_ros2(subparsers)
