"""Log and trajectory readers (ROS 1 bag, ROS 2 sqlite3/MCAP, TUM/KITTI/EuRoC) and writers.

The log reader is imported on first use (PEP 562): `ape` on two text files does not pay for it
(~30 ms of a ~1 s run)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from mrnc_eval.io.reader import LogReader, TopicInfo, open_log

__all__ = ["LogReader", "TopicInfo", "open_log"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from mrnc_eval.io import reader

        return getattr(reader, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
