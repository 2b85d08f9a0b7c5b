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


class LazyTypestore:
    """`typestore_for(ros1=...)` made on first use: a log that defines its own types (MCAP, most
    ROS 2 and ROS 1 bags) never needs the standard store, whose modules take ~65 ms to import.
    Stands in for a typestore wherever only `fielddefs` is read (rosbags' AnyReader default)."""

    def __init__(self, *, ros1: bool) -> None:
        self._ros1 = ros1
        self._store: Any = None

    @property
    def fielddefs(self) -> Any:
        if self._store is None:
            self._store = typestore_for(ros1=self._ros1)
        return self._store.fielddefs
