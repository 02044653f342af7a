"""Reading ROS 2 channels (``ros2msg`` schemas, CDR messages) as the project's samples: the channel adapters."""
