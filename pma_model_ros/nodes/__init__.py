"""ROS 2 nodes: thin shells converting messages to and from :mod:`pma_model_ros.core`."""
