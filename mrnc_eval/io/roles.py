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
4. Inputs never come from ground truth: a topic that is the ground-truth role's topic, or whose
   name marks it as truth (ground_truth, truth, gt, mocap, vicon, optitrack, qualisys), never gets
   an input role (INPUT_ROLES). A pose topic named so takes the ground_truth role; the others are
   left out. When that leaves an input role without a topic, a TruthExclusion says why; an
   override that names such a topic for an input role is refused.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from mrnc_eval.errors import ConfigError

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
# roles whose topic feeds an estimate (SLAM, control replay): never ground truth (rule 4)
INPUT_ROLES = ("lidar", "imu", "chassis_imu", "gnss", "wheel_odom", "wheel_speeds", "commands", "cmd_vel")
# names that mark a topic as truth: whole words (split at / _ - . and spaces) ...
_TRUTH_WORDS = ("truth", "groundtruth", "gt", "mocap", "vicon", "optitrack", "qualisys", "motioncapture")
# ... and word pairs
_TRUTH_PAIRS = ("ground_truth", "ground-truth", "motion_capture")
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
    """A role with several candidate topics and the one chosen."""

    role: str
    chosen: str
    alternatives: tuple[str, ...]  # the other candidates, best first
    reason: str  # why the chosen one won (or why it is doubtful)

    def message(self) -> str:
        others = ", ".join(self.alternatives) if self.alternatives else "no other candidate"
        return (f"role {self.role}: using {self.chosen} ({self.reason}); other candidates: {others}; "
                f"choose with --set io.roles.{self.role}=TOPIC")


@dataclass(frozen=True)
class TruthExclusion:
    """A topic kept out of an input role because it is (or is named like) ground truth, reported
    when the role is left without a topic."""

    role: str  # the input role its message type fits
    topic: str
    reason: str

    @property
    def chosen(self) -> str:  # the topic a finding is about (as Ambiguity.chosen)
        return self.topic

    def message(self) -> str:
        what = "wheel odometry" if self.role == "wheel_odom" else self.role.replace("_", " ")
        return (f"{self.topic} is not used as {what}: {self.reason}; inputs never come from "
                f"ground truth, so the run has no {self.role} input")


def truth_marker(topic: str) -> str | None:
    """The word of `topic` that marks it as ground truth (rule 4), or None."""
    low = topic.lower()
    for pair in _TRUTH_PAIRS:
        if pair in low:
            return pair
    words = [w for w in re.split(r"[/_\-.\s]+", low) if w]
    return next((w for w in words if w in _TRUTH_WORDS), None)


def _is_ground_truth(topic: str) -> bool:
    return truth_marker(topic) is not None


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


def _truth_reason(topic: str, truth_topic: str | None) -> str | None:
    """Why `topic` may not be an input (rule 4), or None."""
    word = truth_marker(topic)
    if word is not None:
        return f"its name marks it as ground truth ({word!r})"
    return "it is the run's ground-truth source (role ground_truth)" if topic == truth_topic else None


def _refuse_truth_overrides(overrides: dict[str, str], truth_topic: str | None) -> None:
    for role, topic in overrides.items():
        why = _truth_reason(topic, truth_topic) if role in INPUT_ROLES else None
        if why:
            raise ConfigError(f"io.roles.{role}={topic}: {why}; an input never comes from ground truth "
                              "(rename the topic in the log, or choose another)")


def without_truth(found: dict[str, list[Candidate]], overrides: dict[str, str]
                  ) -> tuple[dict[str, list[Candidate]], list[TruthExclusion]]:
    """`found` with every ground-truth topic taken out of the input roles (rule 4), and the
    exclusions that left an input role without a topic. A truth-named Odometry (role ground_truth)
    counts as taken out of wheel_odom."""
    gt = found.get("ground_truth", [])
    truth_topic = overrides.get("ground_truth") or (rank("ground_truth", gt)[0].topic if gt else None)
    _refuse_truth_overrides(overrides, truth_topic)
    kept: dict[str, list[Candidate]] = {}
    left_out: dict[str, list[TruthExclusion]] = {}
    for role, cands in found.items():
        keep = []
        for c in cands:
            why = _truth_reason(c.topic, truth_topic) if role in INPUT_ROLES else None
            if why:
                left_out.setdefault(role, []).append(TruthExclusion(role, c.topic, why))
            else:
                keep.append(c)
        if keep:
            kept[role] = keep
    for c in gt:
        if c.msgtype == "nav_msgs/msg/Odometry":
            why = _truth_reason(c.topic, truth_topic) or "its name marks it as ground truth"
            left_out.setdefault("wheel_odom", []).append(TruthExclusion("wheel_odom", c.topic, why))
    notes = [e for role, es in left_out.items() if role not in kept and role not in overrides for e in es]
    return kept, notes


def choose_roles(found: dict[str, list[Candidate]], overrides: dict[str, str]
                 ) -> tuple[dict[str, str], list[Ambiguity | TruthExclusion]]:
    """role -> topic (rule 2; overrides win; rule 4: never ground truth as an input) and the
    ambiguities and truth exclusions to warn about (rules 3 and 4)."""
    roles: dict[str, str] = {}
    found, excluded = without_truth(found, overrides)
    doubts: list[Ambiguity | TruthExclusion] = list(excluded)
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

