"""LogReader: typed, header-stamped time series out of ROS 1 / ROS 2 logs.

The reader is the one entry point; each job lives in its own module:
  io/log_source.py      opening the log, raw messages, decoding (library errors -> InputError)
  io/overview.py        the one scan: stamps, counts, gaps per topic; the small topics' cache
  io/role_detection.py  which topic plays which role (io/roles.py's rule)
  io/stream_health.py   duplicates, out-of-order stamps, validation drops, as warnings
  io/series.py          the typed series (IMU, GNSS, wheel speeds, twists, path, poses, sweeps)
  io/tf_tree.py         static transforms and TF chains
Streams are sorted by header stamp; duplicate and out-of-order stamps are counted
(StreamHealth), never silently passed on. Sweeps are streamed one at a time.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from mrnc_eval.data import GnssSeries, ImuSeries, SidePair, StreamHealth, Sweep, Trajectory, Twists, Waypoints
from mrnc_eval.errors import InputError
from mrnc_eval.io import tf_tree
from mrnc_eval.io.config import IoConfig
from mrnc_eval.io.log_source import LogSource, expand_paths
from mrnc_eval.io.overview import TopicInfo, scan
from mrnc_eval.io.role_detection import detect_roles
from mrnc_eval.io.roles import Ambiguity, TruthExclusion
from mrnc_eval.io.series import SeriesReader
from mrnc_eval.io.stream_health import HealthLedger

__all__ = ["LogReader", "TopicInfo", "open_log"]


class LogReader:
    """An open log. Use `open_log(path)`; close it (or use `with`)."""

    def __init__(self, paths: list[Path], io_cfg: IoConfig | None = None) -> None:
        self.cfg = io_cfg or IoConfig()
        self.source = LogSource(paths)
        self.paths = paths
        self.path = self.source.path
        self.container = self.source.container
        self._ledger = HealthLedger(self.path, self.cfg.validation)
        self._series = SeriesReader(src=self.source, health=self._ledger, cfg=self.cfg)
        self._stats: dict[str, TopicInfo] | None = None
        self._stamps: dict[str, np.ndarray] = {}
        self._roles: dict[str, str] | None = None
        self.role_doubts: list[Ambiguity | TruthExclusion] = []  # io/roles.py rules 3 and 4

    # ------------------------------------------------------------------ lifecycle
    def close(self) -> None:
        self.source.close()

    def __enter__(self) -> LogReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ overview and roles
    @property
    def topics(self) -> list[TopicInfo]:
        return list(self._overview().values())

    def _overview(self) -> dict[str, TopicInfo]:
        """The scan of the log (once), each topic labelled with its role."""
        if self._stats is None:
            stats, self._stamps = scan(self.source, self._ledger, self.cfg.small_topic_cache_mb)
            by_topic: dict[str, str] = {}
            for role, topic in self.roles.items():
                by_topic.setdefault(topic, role)
            self._stats = {t: TopicInfo(**{**s.__dict__, "role": by_topic.get(t)}) for t, s in stats.items()}
        return self._stats

    def topic_types(self) -> dict[str, str]:
        """topic -> message type, from the container's index (no scan)."""
        return {t: ch.msgtype for t, ch in self.source.channels.items()}

    @property
    def roles(self) -> dict[str, str]:
        """role -> topic, from message types and the container's index (no scan of the log:
        only the first message of each JointState topic is read, for its joint names)."""
        if self._roles is None:
            self._roles, self.role_doubts = detect_roles(self.source, self.cfg.roles)
        return dict(self._roles)

    def has_role(self, role: str) -> bool:
        return role in self.roles

    def _topic_for(self, role: str, topic: str | None) -> str:
        if topic is not None:
            if topic not in self.source.channels:
                raise InputError(self.path, "requested topic is absent", topic=topic)
            return topic
        found = self.roles.get(role)
        if found is None:
            raise InputError(self.path, f"no topic with role {role!r} (set io.roles.{role} to choose one)")
        return found

    @property
    def start_s(self) -> float:
        firsts = [s.first_s for s in self.topics if s.first_s is not None and s.role not in ("tf_static", "path")]
        return min(firsts) if firsts else 0.0

    @property
    def end_s(self) -> float:
        lasts = [s.last_s for s in self.topics if s.last_s is not None and s.role not in ("tf_static", "path")]
        return max(lasts) if lasts else 0.0

    @property
    def duration_s(self) -> float:
        return self.end_s - self.start_s

    def stamps(self, topic: str) -> np.ndarray:
        """Header stamps (s) of a topic in log order, as recorded (record times for types
        without a header); from the one scan of the log, so free after `topics`."""
        self.source.channel(topic)
        self._overview()
        return self._stamps[topic].copy()

    def sweep_stamps(self, topic: str | None = None) -> np.ndarray:
        return self.stamps(self._topic_for("lidar", topic))

    # ------------------------------------------------------------------ health
    def health(self, topic: str) -> StreamHealth:
        """Counts of the raw stream (duplicates, out-of-order stamps, largest gap) and notes
        from reading it (e.g. sweeps skipped)."""
        self._overview()
        return self._ledger.get(topic)

    def health_notes(self) -> list[str]:
        """One line per problem found in the streams read so far (dropped samples, sorted or
        duplicate stamps, skipped sweeps), for a result's warnings."""
        return self._ledger.notes()

    # ------------------------------------------------------------------ typed series (io/series.py)
    def imu(self, topic: str | None = None, *, fast: bool = True) -> ImuSeries:
        """IMU samples sorted by header stamp, duplicates dropped (counted in `health`);
        `fast=False` deserialises each message (same result, for checks)."""
        return self._series.imu(self._topic_for("imu", topic), fast=fast)

    def gnss(self, topic: str | None = None) -> GnssSeries:
        return self._series.gnss(self._topic_for("gnss", topic))

    def wheel_speeds(self, topic: str | None = None, wheel_radius_m: float = 0.35) -> SidePair:
        """Wheel surface speeds (m/s) from JointState angular velocities (rad/s)."""
        return self._series.joint_pair(self._topic_for("wheel_speeds", topic), scale=wheel_radius_m, unit="m/s",
                                       exclude="pump")

    def commands(self, topic: str | None = None) -> SidePair:
        """Per-side pump commands (RPM) from JointState velocities."""
        return self._series.joint_pair(self._topic_for("commands", topic), scale=1.0, unit="RPM", exclude=None)

    def cmd_vel(self, topic: str | None = None) -> Twists:
        return self._series.cmd_vel(self._topic_for("cmd_vel", topic))

    def odometry_twist(self, topic: str | None = None) -> Twists:
        """The body twist of an Odometry topic (default: the wheel odometry): forward speed m/s and
        yaw rate rad/s, in its child frame (nav_msgs/Odometry's convention)."""
        return self._series.odometry_twist(self._topic_for("wheel_odom", topic))

    def waypoints(self, topic: str | None = None) -> Waypoints:
        return self._series.waypoints(self._topic_for("path", topic))

    def trajectory(self, topic: str) -> Trajectory:
        """Poses of a PoseStamped / PoseWithCovarianceStamped / Odometry / TransformStamped topic,
        or of a TF child frame given as "/tf:parent.child"."""
        if topic.startswith("/tf:") or topic.startswith("/tf_static:"):
            return tf_tree.tf_trajectory(self._series, topic, self.roles.get("tf_static"))
        return self._series.poses(topic)

    def ground_truth(self, topic: str | None = None) -> Trajectory:
        return self.trajectory(self._topic_for("ground_truth", topic))

    def wheel_odometry(self, topic: str | None = None) -> Trajectory:
        return self.trajectory(self._topic_for("wheel_odom", topic))

    def sweeps(self, topic: str | None = None, *, keep: Callable[[float], bool] | None = None,
               note_skips: bool = True) -> Iterator[Sweep]:
        """Decoded sweeps in log order, streamed one at a time; a sweep not after the last one
        yielded is skipped and noted (unless `note_skips` is False: a look ahead of the run's own
        pass), one whose header stamp `keep` refuses skipped before decoding."""
        yield from self._series.sweeps(self._topic_for("lidar", topic), keep=keep, note_skips=note_skips)

    def strings(self, topic: str) -> list[str]:
        return self._series.strings(topic)

    def messages(self, topic: str, expect: tuple[str, ...] | None = None) -> Iterator[Any]:
        """Decoded messages of a topic (rosbags objects); with `expect`, it must carry one of those types."""
        return self.source.messages(topic, expect)

    # ------------------------------------------------------------------ TF tree (io/tf_tree.py)
    def static_transforms(self) -> dict[tuple[str, str], np.ndarray]:
        return tf_tree.static_transforms(self._series, self.roles.get("tf_static"))

    def transform(self, parent: str, child: str) -> np.ndarray:
        """Pose of `child` in `parent` (4x4), composed along the static TF tree."""
        return tf_tree.static_pose(self.static_transforms(), parent, child, where=self.path)


def open_log(path: str | Path | list[str | Path], io_cfg: IoConfig | None = None) -> LogReader:
    """Open a log: a file, a ROS 2 bag directory, or a recording split into several files of
    one kind (a list, "a.bag,b.bag", or a glob pattern such as "run_*.bag"); raises
    InputError on anything unreadable."""
    items = list(path) if isinstance(path, (list, tuple)) else [path]
    paths = [p for item in items for p in expand_paths(item)]
    if not paths:
        raise InputError("<none>", "no log given")
    return LogReader(paths, io_cfg)
