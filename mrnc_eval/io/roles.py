"""Message roles (which topic is the LiDAR, the IMU, the wheel odometry...), detected by a
documented rule and overridable by topic (`--set io.roles.ROLE=TOPIC`).

The rule, per role:
1. Candidates are the topics with messages whose type fits the role (PointCloud2 -> lidar,
   Imu -> imu or chassis_imu, Odometry -> wheel_odom or ground_truth by name, JointState ->
   commands when its joints name a pump, else wheel_speeds, ...).
2. When several fit, they are ranked, best first, by
   a. the name and frame: a topic whose name or frame says it comes from another source is
      ranked last (lidar: camera, depth, rgbd, stereo...; wheel_odom: filtered, ekf, ukf, fused,
      slam, lio, gps, map...); one whose name says the role is ranked first (lidar: ouster,
      velodyne, lidar...; wheel_odom: wheel);
   b. the expected fields: a LiDAR cloud with a ring and a per-point time field (what deskewing
      needs) before one without; an odometry whose pose is in an `odom` frame (not `map`);
   c. the message count (the rate, on one log): more first;
   d. the topic name, alphabetically (only to make the choice repeatable).
3. A role with several candidates, or whose only candidate looks like another source, is
   reported as an ambiguity: the reader logs a warning naming the alternatives and the override.
"""

from __future__ import annotations

from dataclasses import dataclass

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
POSE_TYPES = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseWithCovarianceStamped")

# words in a topic or frame name (lower case) that say "another source" / "this role"
_OTHER_SOURCE = {
    "lidar": ("camera", "depth", "rgbd", "stereo", "kinect", "realsense", "zed", "radar"),
    "wheel_odom": ("filtered", "ekf", "ukf", "fused", "fusion", "slam", "lio", "loam", "icp", "gps", "gnss",
                   "map", "global", "visual", "vio", "/vo", "estimate"),
}
_THIS_ROLE = {
    "lidar": ("ouster", "os0", "os1", "os2", "velodyne", "lidar", "hesai", "livox", "rslidar", "pandar"),
    "wheel_odom": ("wheel",),
}
_TIME_FIELDS = ("t", "time", "timestamp")
_UNJUDGED = ("tf", "tf_static", "metadata")  # several of these are normal; none feeds a computation by itself


@dataclass(frozen=True)
class Candidate:
    """What is known of a topic without reading it all: its type and message count, and, for
    clouds and odometry, the field names and frames of its first message (when read)."""

    topic: str
    msgtype: str
    count: int
    fields: tuple[str, ...] = ()
    frame_id: str = ""
    child_frame_id: str = ""


@dataclass(frozen=True)
class Ambiguity:
    role: str
    chosen: str
    alternatives: tuple[str, ...]  # the other candidates, best first
    reason: str  # why the chosen one won (or why it is doubtful)

    def message(self) -> str:
        others = ", ".join(self.alternatives) if self.alternatives else "no other candidate"
        return (f"role {self.role}: using {self.chosen} ({self.reason}); other candidates: {others}; "
                f"choose with --set io.roles.{self.role}=TOPIC")


def _is_ground_truth(topic: str) -> bool:
    low = topic.lower()
    return "ground_truth" in low or "groundtruth" in low or low.endswith("/gt") or "/gt/" in low


def role_of(topic: str, msgtype: str, joint_names: list[str]) -> str | None:
    """The role a topic's message type (and name) fits, before any ranking."""
    if msgtype == "tf2_msgs/msg/TFMessage":
        return "tf_static" if topic.endswith("tf_static") else "tf"
    if msgtype == "sensor_msgs/msg/Imu":
        return "chassis_imu" if "chassis" in topic.lower() else "imu"
    if msgtype in POSE_TYPES:
        if _is_ground_truth(topic):
            return "ground_truth"
        return "wheel_odom" if msgtype == "nav_msgs/msg/Odometry" else None
    if msgtype == "sensor_msgs/msg/JointState":
        return "commands" if "pump" in " ".join(joint_names).lower() else "wheel_speeds"
    return _BY_TYPE.get(msgtype)


def _name_score(role: str, c: Candidate) -> int:
    """-1: named like another source; +1: named like this role; 0: neither."""
    text = " ".join((c.topic, c.frame_id, c.child_frame_id)).lower()
    if any(word in text for word in _OTHER_SOURCE.get(role, ())):
        return -1
    return 1 if any(word in text for word in _THIS_ROLE.get(role, ())) else 0


def _fields_score(role: str, c: Candidate) -> int:
    if role == "lidar":
        return int("ring" in c.fields) + int(any(f in c.fields for f in _TIME_FIELDS))
    if role == "wheel_odom":
        return int(c.frame_id.lower().endswith("odom"))
    return 0


def rank(role: str, candidates: list[Candidate]) -> list[Candidate]:
    """Candidates for `role`, best first (module docstring, rule 2)."""
    by_name = sorted(candidates, key=lambda c: c.topic)
    return sorted(by_name, key=lambda c: (_name_score(role, c), _fields_score(role, c), c.count), reverse=True)


def _reason(role: str, best: Candidate, runner_up: Candidate | None) -> str:
    if _name_score(role, best) < 0:
        return "its name suggests another source"
    if runner_up is None:
        return "the only candidate"
    if _name_score(role, best) != _name_score(role, runner_up):
        return "named like a " + role.replace("_", " ") + " topic"
    if _fields_score(role, best) != _fields_score(role, runner_up):
        return "has the expected fields" if role == "lidar" else "pose in an odom frame"
    if best.count != runner_up.count:
        return f"most messages: {best.count} vs {runner_up.count}"
    return "first by name"


def candidates_by_role(topics: list[Candidate], joint_names: dict[str, list[str]]) -> dict[str, list[Candidate]]:
    """role -> the topics that fit it (rule 1), topics without messages left out."""
    found: dict[str, list[Candidate]] = {}
    for c in topics:
        role = role_of(c.topic, c.msgtype, joint_names.get(c.topic, [])) if c.count else None
        if role:
            found.setdefault(role, []).append(c)
    return found


def choose_roles(found: dict[str, list[Candidate]], overrides: dict[str, str]
                 ) -> tuple[dict[str, str], list[Ambiguity]]:
    """role -> topic (rule 2; overrides win) and the ambiguities to warn about (rule 3)."""
    roles: dict[str, str] = {}
    doubts: list[Ambiguity] = []
    for role, cands in found.items():
        ranked = rank(role, cands)
        roles[role] = ranked[0].topic
        doubtful = _name_score(role, ranked[0]) < 0
        if role not in overrides and role not in _UNJUDGED and (len(ranked) > 1 or doubtful):
            doubts.append(Ambiguity(role, ranked[0].topic, tuple(c.topic for c in ranked[1:]),
                                    _reason(role, ranked[0], ranked[1] if len(ranked) > 1 else None)))
    if "imu" not in roles and "chassis_imu" in roles:
        roles["imu"] = roles["chassis_imu"]
    roles.update(overrides)
    return roles, doubts

