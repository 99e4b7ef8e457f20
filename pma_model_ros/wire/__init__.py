"""Serialized ROS 2 messages (CDR bytes) to arrays and back: the nodes' and the bag tools' one wire
layer.  numpy only; a message it cannot read at its cached layout goes to the deserializer it is
given (rclpy's in the nodes, rosbags' offline).
"""
