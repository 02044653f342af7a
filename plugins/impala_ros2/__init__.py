"""impala-flow's ROS 2 plugin: rosbag2 recordings (MCAP, ``ros2msg`` schemas, CDR) in and out.

Reading: adapters turn ROS 2 channels into the project's types (B-scan images and Navtech FFT data into radar beams,
radar_msgs scans into detections, odometry, poses, IMU, GPS fixes and twists) for ``io.Replayer``, ``info``,
``export`` and ``impala-flow import ros2``. Writing: standard ROS 2 messages from recorded samples. The message
definitions both sides use are in :mod:`impala_ros2.msgdefs`.
"""
