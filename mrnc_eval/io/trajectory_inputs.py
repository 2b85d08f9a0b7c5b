"""What a trajectory argument names, for the mistakes newcomers make: a result folder (its
trajectory.tum is meant), or a log without `:/topic` (say it is a log and list its pose topics)."""

from __future__ import annotations

from pathlib import Path

from mrnc_eval.errors import InputError
from mrnc_eval.io.containers import LOG_SUFFIXES
from mrnc_eval.io.roles import POSE_TYPES

RESULT_TRAJECTORY = "trajectory.tum"  # what `slam` writes into each result folder


def trajectory_file_in(path: Path) -> Path:
    """`path` itself when it is a trajectory file; a result folder's trajectory.tum; otherwise
    an InputError that says which file or spec to pass."""
    if not path.exists():
        raise InputError(path, "no such file")
    if path.is_dir() and not (path / "metadata.yaml").exists():
        if (path / RESULT_TRAJECTORY).is_file():
            return path / RESULT_TRAJECTORY
        raise InputError(path, f"is a folder, not a trajectory file (a slam result folder holds {RESULT_TRAJECTORY}; "
                               "pass a TUM, KITTI or EuRoC file)")
    if path.is_dir() or path.suffix.lower() in LOG_SUFFIXES:
        raise InputError(path, f"is a log, not a trajectory file: name a pose topic as {path}:/TOPIC "
                               f"({_pose_topics(path)})")
    return path


def _pose_topics(path: Path) -> str:
    from mrnc_eval.io import open_log

    try:
        with open_log(path) as lg:
            topics = [t for t, msgtype in sorted(lg.topic_types().items()) if msgtype in POSE_TYPES]
    except InputError as err:
        return f"it cannot be opened: {err.problem}"
    return "pose topics: " + ", ".join(topics) if topics else "it has no Odometry or PoseStamped topic"
