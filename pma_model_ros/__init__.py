"""pma_model_ros: static force of Festo pneumatic muscle actuators for ROS 2.

The physics lives in :mod:`pma_model_ros.core` (numpy/scipy only); the ROS 2
nodes in :mod:`pma_model_ros.nodes` are thin shells around it.
"""

__version__ = '0.1.0'
