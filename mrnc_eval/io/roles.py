"""Message roles, detected by message type (and a peek at names), overridable by topic."""

from __future__ import annotations

ROLES = ("lidar", "imu", "chassis_imu", "gnss", "wheel_odom", "wheel_speeds", "commands", "cmd_vel", "path",
         "ground_truth", "tf_static", "tf", "metadata")

_BY_TYPE = {
    "sensor_msgs/msg/PointCloud2": "lidar",
    "sensor_msgs/msg/Imu": "imu",
    "sensor_msgs/msg/NavSatFix": "gnss",
    "nav_msgs/msg/Path": "path",
    "geometry_msgs/msg/TwistStamped": "cmd_vel",
    "geometry_msgs/msg/Twist": "cmd_vel",
    "tf2_msgs/msg/TFMessage": "tf",
    "std_msgs/msg/String": "metadata",
}


def _is_ground_truth(topic: str) -> bool:
    low = topic.lower()
    return "ground_truth" in low or "groundtruth" in low or low.endswith("/gt") or "/gt/" in low


def detect_roles(topics: list[tuple[str, str, int]], joint_names: dict[str, list[str]],
                 overrides: dict[str, str]) -> dict[str, str]:
    """role -> topic. `topics` is (topic, msgtype, count); `joint_names` the first names seen
    on each JointState topic. Overrides win; a second candidate for a role is ignored."""
    roles: dict[str, str] = {}
    for topic, msgtype, count in sorted(topics, key=lambda x: x[0]):
        if count == 0:
            continue
        role = _BY_TYPE.get(msgtype)
        if msgtype == "tf2_msgs/msg/TFMessage":
            role = "tf_static" if topic.endswith("tf_static") else "tf"
        elif msgtype == "sensor_msgs/msg/Imu":
            role = "chassis_imu" if "chassis" in topic.lower() else "imu"
        elif msgtype in ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped",
                         "geometry_msgs/msg/PoseWithCovarianceStamped"):
            if _is_ground_truth(topic):
                role = "ground_truth"
            elif msgtype == "nav_msgs/msg/Odometry":
                role = "wheel_odom"
        elif msgtype == "sensor_msgs/msg/JointState":
            names = " ".join(joint_names.get(topic, [])).lower()
            role = "commands" if "pump" in names else "wheel_speeds"
        if role and role not in roles:
            roles[role] = topic
    if "imu" not in roles and "chassis_imu" in roles:
        roles["imu"] = roles["chassis_imu"]
    roles.update(overrides)
    return roles
