"""What a trajectory argument names, parsed in one place for `ape`, `rpe`, `table` and the API: a
file (TUM, KITTI, EuRoC), a result folder (the trajectory `slam` reports: online unless the
run's slam.table_trajectory says smoothed) or a log with a topic
(`log.bag:/topic`, `a.mcap,b.mcap:/topic`, `bag_dir:/topic`, `log.bag:/tf:odom.base_link`); and the
mistakes newcomers make: a log without `:/topic` (say it is a log and list its pose topics)."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

from mrnc_eval.errors import InputError
from mrnc_eval.io.containers import LOG_SUFFIXES, is_log_file
from mrnc_eval.io.roles import POSE_TYPES

RESULT_TRAJECTORY = "trajectory.tum"  # the smoothed trajectory `slam` writes into each result folder
# slam.table_trajectory -> the file of a slam result folder holding that trajectory
RESULT_TRAJECTORIES = {"online": "trajectory_online.tum", "smoothed": RESULT_TRAJECTORY}
log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TrajectorySpec:
    """A trajectory argument split once. `path` is a file or folder, or for a log what `open_log`
    takes (one file, a ROS 2 bag folder, "a.mcap,b.mcap" or a glob of split files); `topic` is
    the pose topic of a log ("/odom", "/tf:odom.base_link"), None for a file."""

    path: str
    topic: str | None = None

    def __str__(self) -> str:
        return self.path if self.topic is None else f"{self.path}:{self.topic}"

    def relative_to(self, base: Path) -> TrajectorySpec:
        """Relative paths taken from `base` (a manifest's folder); each file of a split log."""
        parts = self.path.split(",") if self.topic is not None else [self.path]
        return TrajectorySpec(",".join(p if Path(p).is_absolute() else str(base / p) for p in parts), self.topic)

    def exists(self) -> bool:
        """Whether the file or folder is there (a log's split files and glob patterns: when
        opened, which names the missing file)."""
        return self.topic is not None or Path(self.path).exists()


def parse_trajectory_spec(spec: str | Path | TrajectorySpec, *, base: Path | None = None) -> TrajectorySpec:
    """`log.bag:/topic` (any log suffix, split logs included) or `bag_dir:/topic` for a ROS 2 bag
    folder; anything else is a file or folder path, taken whole. With `base` (a manifest's folder),
    relative paths are taken from there."""
    if isinstance(spec, TrajectorySpec):
        return spec
    text = str(spec)
    whole = Path(text) if base is None else base / text
    if whole.exists():  # an existing path wins, even with a colon in its name
        return TrajectorySpec(str(whole))
    parsed = TrajectorySpec(str(whole))
    for suffix in LOG_SUFFIXES:
        log_path, marker, topic = text.partition(suffix + ":")
        if marker:
            parsed = TrajectorySpec(log_path + suffix, topic)
            break
    else:
        log_path, marker, topic = text.partition(":/")
        if marker:
            parsed = TrajectorySpec(log_path, "/" + topic)
    return parsed if base is None or parsed.topic is None else parsed.relative_to(base)


def trajectory_file_in(path: Path) -> Path:
    """`path` itself when it is a trajectory file; a result folder's trajectory.tum; otherwise
    an InputError that says which file or spec to pass."""
    if not path.exists():
        raise InputError(path, "no such file")
    if path.is_dir() and not (path / "metadata.yaml").exists():
        chosen = result_trajectory(path)
        if chosen is not None:
            return chosen
        raise InputError(path, f"is a folder, not a trajectory file (a slam result folder holds {RESULT_TRAJECTORY}; "
                               "pass a TUM, KITTI or EuRoC file)")
    if path.is_dir() or is_log_file(path):  # by its first bytes, or its suffix
        raise InputError(path, f"is a log, not a trajectory file: name a pose topic as {path}:/TOPIC "
                               f"({_pose_topics(path)})")
    return path


def result_trajectory(run_dir: Path) -> Path | None:
    """The trajectory of a slam result folder that `slam` and `table` report: the run's
    slam.table_trajectory (config.yaml; online by default), said on stderr so the number can be
    matched; the smoothed one when a run has no online file. None when the folder has neither."""
    import yaml

    which = "online"
    try:
        cfg = yaml.safe_load((run_dir / "config.yaml").read_text(encoding="utf-8")) or {}
        which = str(cfg.get("slam", {}).get("table_trajectory", "online"))
    except (OSError, yaml.YAMLError, AttributeError):
        pass
    for name in (RESULT_TRAJECTORIES.get(which, RESULT_TRAJECTORIES["online"]), RESULT_TRAJECTORY):
        if (run_dir / name).is_file():
            other = [n for n in RESULT_TRAJECTORIES.values() if n != name and (run_dir / n).is_file()]
            log.warning("%s: using %s (the %s trajectory, as slam and table report it)%s", run_dir, name,
                        "online" if name != RESULT_TRAJECTORY else "smoothed",
                        f"; pass {run_dir / other[0]} for the other" if other else "")
            return run_dir / name
    return None


def _pose_topics(path: Path) -> str:
    from mrnc_eval.io import open_log

    try:
        with open_log(path) as lg:
            topics = [t for t, msgtype in sorted(lg.topic_types().items()) if msgtype in POSE_TYPES]
    except InputError as err:
        return f"it cannot be opened: {err.problem}"
    return "pose topics: " + ", ".join(topics) if topics else "it has no Odometry or PoseStamped topic"
