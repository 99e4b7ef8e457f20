"""The nodes' decisions without ROS, for the nodes and the bag tools: the estimation engine."""
