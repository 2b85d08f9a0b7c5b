"""Where a log's ground-truth sidecar lives: `<log name without suffix>.gt.tum` beside the log.

The simulator writes it there and the SLAM command looks for it there; the convention is
defined once, here, so neither has to import the other."""

from __future__ import annotations

from pathlib import Path

LOG_SUFFIXES = (".mcap", ".db3", ".bag")


def gt_tum_path(log_path: Path) -> Path:
    """`<log name without suffix>.gt.tum` beside the log."""
    name = log_path.name
    for suffix in LOG_SUFFIXES:
        name = name.removesuffix(suffix)
    return log_path.with_name(name + ".gt.tum")
