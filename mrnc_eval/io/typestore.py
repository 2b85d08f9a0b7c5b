"""The rosbags typestore both the readers and the writers use: one definition of the message types."""

from __future__ import annotations

from typing import Any


def typestore_for(*, ros1: bool) -> Any:
    """rosbags' typestore for ROS 1 Noetic or ROS 2 Humble, with tf2_msgs added for ROS 1."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in ts.types:
        ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    return ts
