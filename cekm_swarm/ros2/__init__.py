"""ROS 2 interoperability without ROS 2 (docs/ros2.md), one module per concept:

- :mod:`.interfaces`: the ROS 2 message types, per distribution (definitions, CDR, the
  stated Jazzy type hashes), from the ``rosbags`` package;
- :mod:`.mapping`: the project's keys -> standard ROS 2 messages (pure);
- :mod:`.wire`: ``rmw_zenoh``'s wire format (key expressions, attachments, liveliness
  tokens, QoS text, GIDs) (pure);
- :mod:`.teleop`: Twists on ``/<robot>/cmd_vel`` -> the robot's wheel command (pure);
- :mod:`.bag`: ``cekm log export RUN.mcap --to ros2``, a rosbag2 bag of a run's log;
- :mod:`.bridge`: ``cekm ros2 bridge``, the live process, a shell around the above;
- :mod:`.commands`: the two CLI commands.
"""
