"""Where a log's ground truth is: its ground-truth topic, else the sidecar `<log name without
suffix>.gt.tum` beside the log.

The simulator writes the sidecar there and the SLAM command looks for it there; the convention is
defined once, here, so neither has to import the other."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from mrnc_eval.io.containers import LOG_SUFFIXES

if TYPE_CHECKING:
    from mrnc_eval.data import Trajectory
    from mrnc_eval.io.reader import LogReader


def gt_tum_path(log_path: Path) -> Path:
    """`<log name without suffix>.gt.tum` beside the log."""
    name = log_path.name
    for suffix in LOG_SUFFIXES:
        name = name.removesuffix(suffix)
    return log_path.with_name(name + ".gt.tum")


def ground_truth_of(lg: LogReader, log_path: Path) -> Trajectory | None:
    """The log's ground-truth topic, else the `<log>.gt.tum` sidecar beside it, else None."""
    from mrnc_eval.io.trajectory_files import read_tum

    if lg.has_role("ground_truth"):
        return lg.ground_truth()
    beside = gt_tum_path(log_path)
    return read_tum(beside) if beside.is_file() else None


def ground_truth_spec(lg: LogReader, log_path: Path) -> str | None:
    """Where `ground_truth_of` found the ground truth, as a trajectory spec with an absolute path
    (`/abs/log.mcap:/ground_truth` or `/abs/log.gt.tum`): recorded with a run, so `table` reads
    the same reference later from any folder."""
    if lg.has_role("ground_truth"):
        files = ",".join(str(p.resolve()) for p in lg.paths)  # a split log: every file
        return f"{files}:{lg.roles['ground_truth']}"
    beside = gt_tum_path(log_path)
    return str(beside.resolve()) if beside.is_file() else None
