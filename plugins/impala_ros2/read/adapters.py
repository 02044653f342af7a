"""Which adapter reads which ROS 2 type: the table the plugin registers (``registry.add_channel_adapter``)."""

from __future__ import annotations

from typing import Any

from impala_flow.io import ANY_SCHEMA, AdaptedChannel, AdapterContext

from .. import msgdefs
from .cdr import CDR, ROS2IDL, ROS2MSG
from .motion import ImuAdapter, NavSatAdapter, PoseAdapter, RadarScanAdapter, TwistAdapter
from .radar import BScanAdapter, FftAdapter

__all__ = ["ADAPTERS", "register_adapters", "refuse_idl"]

#: ROS 2 type -> adapter class (each gives samples of its ``value_type``)
ADAPTERS: dict[str, type] = {
    "sensor_msgs/Image": BScanAdapter,
    "messages/RadarFftDataMessage": FftAdapter,
    "radar_msgs/RadarScan": RadarScanAdapter,
    "nav_msgs/Odometry": PoseAdapter,
    "geometry_msgs/PoseStamped": PoseAdapter,
    "geometry_msgs/TransformStamped": PoseAdapter,
    "sensor_msgs/Imu": ImuAdapter,
    "sensor_msgs/NavSatFix": NavSatAdapter,
    "geometry_msgs/TwistStamped": TwistAdapter,
}


def refuse_idl(channel: AdaptedChannel, context: AdapterContext) -> Any:
    """Channels whose definition is OMG IDL (``ros2idl``) are refused: mcap-ros2-support decodes ``ros2msg``
    definitions only."""
    raise ValueError("ros2idl (OMG IDL) definitions are not read: mcap-ros2-support decodes ros2msg definitions "
                     "only; record with the .msg definitions (rosbag2's default) or convert the bag")


def register_adapters(registry: Any) -> None:
    for name, cls in ADAPTERS.items():
        registry.add_channel_adapter(ROS2MSG, msgdefs.schema_name(name), CDR, cls)
    registry.add_channel_adapter(ROS2IDL, ANY_SCHEMA, CDR, refuse_idl)
