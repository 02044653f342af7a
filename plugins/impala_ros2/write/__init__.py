"""Writing ROS 2: the recorded streams as standard ROS 2 messages (the ``ros2`` output format)."""

from .writer import PATH_MAX_POSES, TURN_MAX_BYTES, Ros2Writer, ros_topic

__all__ = ["Ros2Writer", "ros_topic", "PATH_MAX_POSES", "TURN_MAX_BYTES"]
