"""The overview pass: one read of the whole log for every topic's stamps, counts and gaps.

Header stamps come straight from the serialised bytes (record times for unstamped types);
the raw messages of small topics are kept (io.small_topic_cache_mb) so the typed series do
not read the file again. MCAP files and ROS 1 bags are read through their indexes, the
clouds left compressed (io/chunk_prefix.py); without a usable index, the full read.
"""

from __future__ import annotations

from array import array
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from mrnc_eval.errors import InputError
from mrnc_eval.io.chunk_prefix import WHOLE, IndexUnusable
from mrnc_eval.io.library_errors import data_errors
from mrnc_eval.io.log_source import LogSource, RawMessages, header_stamps
from mrnc_eval.io.mcap_index import HEAD, IndexedMessages
from mrnc_eval.io.mcap_index import overview as mcap_overview
from mrnc_eval.io.sources import RosbagsSource
from mrnc_eval.io.stream_health import HealthLedger, sort_dedup

_BULK_TYPES = {  # never kept in memory by the overview pass
    "sensor_msgs/msg/PointCloud2", "sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage",
    "sensor_msgs/msg/LaserScan",
}
_STAMPED_FIRST_FIELD = {  # message types whose first field is std_msgs/Header
    "sensor_msgs/msg/PointCloud2", "sensor_msgs/msg/Imu", "sensor_msgs/msg/NavSatFix", "sensor_msgs/msg/JointState",
    "nav_msgs/msg/Odometry", "nav_msgs/msg/Path", "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped", "geometry_msgs/msg/TwistStamped",
    "geometry_msgs/msg/TransformStamped",
}
_HEADER_BYTES = HEAD  # serialised bytes up to the end of a header stamp (ROS 1 and CDR): 12


@dataclass(frozen=True)
class TopicInfo:
    """One topic as the overview pass found it."""

    topic: str
    msgtype: str
    count: int
    role: str | None
    rate_hz: float
    max_gap_s: float
    first_s: float | None
    last_s: float | None
    duplicates: int
    out_of_order: int
    problem: str | None = None  # why the topic cannot be decoded (unknown type, unsupported encoding)


def scan(src: LogSource, health: HealthLedger, cache_mb: float) -> tuple[dict[str, TopicInfo], dict[str, np.ndarray]]:
    """Every topic's TopicInfo (no role yet) and stamps (s, log order); each stream's counts go
    to `health` and the small topics' messages to `src.cache`."""
    header_topics = {t for t, ch in src.channels.items()
                     if ch.msgtype in _STAMPED_FIRST_FIELD and ch.encoding in ("ros1", "cdr")}
    keep = {t for t, ch in src.channels.items() if ch.msgtype not in _BULK_TYPES and not ch.problem}
    wants = {t: WHOLE if t in keep else _HEADER_BYTES if t in header_topics else 0 for t in src.channels}
    no_index: tuple[type[Exception], ...] = (IndexUnusable, InputError, *data_errors())  # or a broken log
    try:  # MCAP, ROS 1: from the indexes, the clouds left compressed (io/chunk_prefix.py)
        if src.container == "ros1" and isinstance(src.src, RosbagsSource):
            records = src.src.indexed_overview(list(src.channels), wants)
            arrays, cache = _collect(src, records, header_topics, keep, cache_mb)
        else:
            parts = _mcap_overviews(src, wants, int(cache_mb * 1e6))
            arrays, cache = _collect_indexed(src, parts, header_topics, keep)
    except no_index:  # the full read, and its own error
        arrays, cache = _collect(src, src.iterate(list(src.channels)), header_topics, keep, cache_mb)
    src.cache = cache
    stats: dict[str, TopicInfo] = {}
    for topic, ch in src.channels.items():
        arr = arrays[topic]
        _, stream = sort_dedup(arr, topic)
        health.set(stream)
        span = float(arr.max() - arr.min()) if arr.size > 1 else 0.0
        stats[topic] = TopicInfo(
            topic=topic, msgtype=ch.msgtype, count=int(arr.size), role=None,
            rate_hz=(arr.size - 1) / span if span > 0 else 0.0, max_gap_s=stream.max_gap_s,
            first_s=float(arr.min()) if arr.size else None, last_s=float(arr.max()) if arr.size else None,
            duplicates=stream.duplicates, out_of_order=stream.out_of_order, problem=ch.problem,
        )
    return stats, arrays


def _mcap_overviews(src: LogSource, wants: dict[str, int], budget: int) -> list[IndexedMessages]:
    """The overview's messages of each file of an MCAP log (a split log: file after file) from
    the indexes, the whole messages kept while they come to `budget` bytes at most (else none);
    IndexUnusable when the log has none that can be trusted."""
    if src.container not in ("mcap", "ros2-mcap") or not all(p.is_file() for p in src.paths):
        raise IndexUnusable(src.container)
    parts: list[IndexedMessages] = []
    for path in src.paths:
        parts.append(mcap_overview(path, wants, budget, index=src.mcap_index() if len(src.paths) == 1 else None))
        budget -= parts[-1].kept
    return parts


def _collect_indexed(src: LogSource, parts: list[IndexedMessages], header_topics: set[str],
                     keep: set[str]) -> tuple[dict[str, np.ndarray], dict[str, RawMessages]]:
    """`_collect` of the index's arrays: each topic's stamps (header stamps or record times) and
    the small topics' messages (none when over the cache budget); a header too short for its stamp
    raises IndexUnusable (the full read then names it)."""
    stamps: dict[str, np.ndarray] = {}
    dropped = any(part.dropped for part in parts)  # over budget: each series reads the file again
    cache: dict[str, RawMessages] = {} if dropped else {t: [] for t in keep}
    for topic in src.channels:
        pieces = [np.zeros(0)]
        for part in parts:
            if topic not in part.topics:
                continue
            sel = np.flatnonzero(part.topic == part.topics.index(topic))
            if topic in header_topics:
                if np.any(part.head_len[sel] < _HEADER_BYTES):
                    raise IndexUnusable("message too short for a header")
                pieces.append(header_stamps(part.head[sel], ros1=src.channels[topic].encoding == "ros1"))
            else:
                pieces.append(part.log_time[sel] * 1e-9)
            if topic in keep and not dropped:
                data, times = part.data, part.log_time[sel].tolist()
                cache[topic] += [(t, data[i] or b"") for t, i in zip(times, sel.tolist(), strict=True)]
        stamps[topic] = np.concatenate(pieces)
    return stamps, cache


def _collect(src: LogSource, records: Iterable[tuple[str, int, bytes]], header_topics: set[str], keep: set[str],
             cache_mb: float) -> tuple[dict[str, np.ndarray], dict[str, RawMessages]]:
    """Stamps of every topic and the small topics' messages (none when over the cache budget)."""
    stamps = {t: array("d") for t in src.channels}  # 8 bytes a stamp (a list costs 32)
    budget = int(cache_mb * 1e6)
    cache: dict[str, RawMessages] = {t: [] for t in keep}
    for topic, t_rec, raw in records:
        if topic in keep:
            budget -= len(raw)
            if budget >= 0:
                cache[topic].append((t_rec, bytes(raw)))
        if topic in header_topics:
            stamps[topic].append(src.checked_header_stamp(raw, topic))
        else:
            stamps[topic].append(t_rec * 1e-9)
    arrays = {t: np.frombuffer(v, dtype=np.float64) if len(v) else np.zeros(0) for t, v in stamps.items()}
    return arrays, cache if budget >= 0 else {}  # over budget: each series reads the file again
