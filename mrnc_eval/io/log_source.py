"""An open log's raw access: its channels, raw messages in log order, decoding on request.

The one place where the reading libraries' exceptions on opening, iterating and decoding
become InputError naming the file and topic. The small topics' raw messages kept by the
overview pass (io/overview.py) are served from `cache` instead of reading the file again.
"""

from __future__ import annotations

import contextlib
import glob
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from mrnc_eval.errors import InputError
from mrnc_eval.io.chunk_prefix import IndexUnusable
from mrnc_eval.io.containers import describe_error, detect_container, openable
from mrnc_eval.io.library_errors import data_errors
from mrnc_eval.io.ros2_mcap import NotPlain, Ros2McapSource, read_summary
from mrnc_eval.io.sources import Channel, McapSource, RosbagsSource
from mrnc_eval.io.split_logs import SplitSource, split_log_paths

RawMessages = list[tuple[int, bytes]]  # (record time ns, serialised message)


class LogSource:
    """The raw side of an open log (what LogReader reads through); close it."""

    def __init__(self, paths: list[Path]) -> None:
        self.paths = paths
        self.path = paths[0]
        self.container = detect_container(paths)
        self._links = contextlib.ExitStack()  # rosbags' view of files whose suffix is not theirs; closed with the log
        try:
            self.src = self._open_source(self._links.enter_context(openable(paths, self.container)))
        except InputError:
            self._links.close()
            raise
        except data_errors() as err:  # rosbags/mcap/sqlite raise many unrelated types for broken files
            self._links.close()
            raise InputError(self.path, f"cannot open {self.container} log: {describe_error(err)}") from err
        self.channels: dict[str, Channel] = self.src.channels
        if not self.channels:
            self.close()
            raise InputError(self.path, "log has no topics (empty bag)")
        self.cache: dict[str, RawMessages] = {}  # small topics' raw messages from the overview pass
        self._index: Any = None  # a single MCAP file's chunk indexes (mcap_index.Index), read once

    def mcap_index(self) -> Any:
        """A single MCAP file's `mcap_index.chunk_indexes` (its summary), read once for the roles,
        the overview and the sweep stream; IndexUnusable as there (not kept: asked again, it is read again)."""
        if self._index is None:
            from mrnc_eval.io.mcap_index import chunk_indexes, summary_indexes

            if isinstance(self.src, Ros2McapSource):  # the summary it was opened from
                self._index = summary_indexes(self.src.summary)
            else:
                with self.path.open("rb") as fh:
                    self._index = chunk_indexes(fh)
        return self._index

    def _open_source(self, named: list[Path]) -> McapSource | RosbagsSource | Ros2McapSource | SplitSource:
        """The reading library for the container; `named`: the paths as rosbags can open them. A
        single ROS 2 MCAP file from its summary when it is plainly well-formed (io/ros2_mcap.py)."""
        if self.container != "ros1" and len(named) > 1:  # split ROS 2 / MCAP: one source per file
            return SplitSource([McapSource(p) if self.container == "mcap" else RosbagsSource([p], ros1=False)
                                for p in named], self.paths)
        if self.container == "mcap":
            return McapSource(self.path)
        if self.container == "ros2-mcap" and len(named) == 1 and named[0].is_file():
            fallback: tuple[type[Exception], ...] = (NotPlain, *data_errors())
            try:
                return Ros2McapSource(named[0], read_summary(self.path))
            except fallback:  # AnyReader opens it, with its own checks and errors
                pass
        return RosbagsSource(named, ros1=self.container == "ros1")

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.src.close()
        self._links.close()

    def channel(self, topic: str) -> Channel:
        ch = self.channels.get(topic)
        if ch is None:
            names = sorted(self.channels)
            listed = ", ".join(names[:12]) + (f", ... ({len(names)} in all)" if len(names) > 12 else "")
            raise InputError(self.path, f"topic not in log (topics: {listed})", topic=topic)
        return ch

    def msgtype(self, topic: str) -> str:
        return self.channel(topic).msgtype

    def iterate(self, topics: list[str]) -> Iterator[tuple[str, int, bytes]]:
        """(topic, record time ns, raw message) in log order; library errors become InputError."""
        try:
            yield from self.src.messages(topics)
        except InputError:
            raise
        except data_errors() as err:
            where = topics[0] if len(topics) == 1 else None
            raise InputError(self.path, f"corrupted or truncated data: {describe_error(err)}", topic=where) from err

    def raw(self, topic: str) -> Iterator[tuple[int, bytes]]:
        """(record time ns, raw message) of one topic, from the overview's cache when it holds them."""
        ch = self.channel(topic)
        if ch.problem:
            raise InputError(self.path, ch.problem, topic=topic)
        if topic in self.cache:
            yield from self.cache[topic]
            return
        for _topic, t_rec, raw in self.iterate([topic]):
            yield t_rec, raw

    def first_raw(self, topic: str) -> bytes | None:
        """`raw(topic)`'s first message (None without one): from the overview's cache, else from
        a single MCAP file's indexes (io/mcap_index.py: only its chunk's beginning decompressed),
        else through the library."""
        self.check_type(topic, None)
        if topic not in self.cache and self.container in ("mcap", "ros2-mcap") and len(self.paths) == 1:
            from mrnc_eval.io.mcap_index import first_message

            with contextlib.suppress(IndexUnusable, *data_errors()):  # the library then reads it, or says why not
                return first_message(self.path, topic, index=self.mcap_index())
        return next((bytes(raw) for _t, raw in self.raw(topic)), None)

    def stream(self, topic: str) -> Iterator[tuple[int, bytes | memoryview]]:
        """`raw(topic)` for one large topic (the clouds): from a single MCAP file straight from its
        chunks (io/mcap_stream.py: each chunk decompressed once, no copies), each message valid
        until the next is asked for; through the library when that cannot be planned."""
        ch = self.channel(topic)
        if ch.problem:
            raise InputError(self.path, ch.problem, topic=topic)
        plan = None
        if topic not in self.cache and self.container in ("mcap", "ros2-mcap") and len(self.paths) == 1:
            from mrnc_eval.io.mcap_stream import TopicStream

            with contextlib.suppress(IndexUnusable, *data_errors()):  # the library then reads it, or says why not
                plan = TopicStream(self.path, topic, index=self.mcap_index())
        yield from plan.messages() if plan is not None else self.raw(topic)

    def decode(self, raw: bytes, topic: str) -> Any:  # a rosbags message object
        try:
            return self.src.deserialize(raw, topic)
        except data_errors() as err:
            raise InputError(self.path, f"cannot decode {self.msgtype(topic)} message: {describe_error(err)}",
                             topic=topic) from err

    def check_type(self, topic: str, expect: tuple[str, ...] | None) -> None:
        """The topic is decodable and (with `expect`) carries one of those types."""
        ch = self.channel(topic)
        if ch.problem:
            raise InputError(self.path, ch.problem, topic=topic)
        if expect is not None and ch.msgtype not in expect:
            raise InputError(self.path, f"expected {' or '.join(expect)}, got {ch.msgtype}", topic=topic)

    def timed_messages(self, topic: str, expect: tuple[str, ...] | None = None) -> Iterator[tuple[float, Any]]:
        """(record time s, message); with `expect`, the topic must carry one of those types."""
        self.check_type(topic, expect)
        for t_rec, raw in self.raw(topic):
            yield t_rec * 1e-9, self.decode(raw, topic)

    def messages(self, topic: str, expect: tuple[str, ...] | None = None) -> Iterator[Any]:
        for _t, msg in self.timed_messages(topic, expect):
            yield msg

    def header_stamp(self, raw: bytes | memoryview, topic: str | None = None) -> float:
        """Header stamp straight from the serialised bytes (no full decode).
        ROS 1: seq u32, then sec u32, nsec u32. CDR: 4-byte encapsulation header (byte 1 odd:
        little endian), then sec i32, nanosec u32."""
        ros1 = self.channels[topic].encoding == "ros1" if topic else self.container == "ros1"
        if ros1:
            sec, nsec = struct.unpack_from("<II", raw, 4)
        else:
            sec, nsec = struct.unpack_from("<iI" if raw[1] & 1 else ">iI", raw, 4)
        return float(sec + nsec * 1e-9)

    def checked_header_stamp(self, raw: bytes | memoryview, topic: str) -> float:
        """`header_stamp`, a message too short for one an InputError."""
        try:
            return self.header_stamp(raw, topic)
        except (struct.error, IndexError) as err:
            raise InputError(self.path, f"message too short for a header: {err}", topic=topic) from err


def header_stamps(heads: np.ndarray, *, ros1: bool) -> np.ndarray:
    """`LogSource.header_stamp` of many messages at once, from their first 12 bytes ((N, 12) uint8;
    CDR: each message's own byte order); the same floats to the bit."""
    sec, nsec = np.ascontiguousarray(heads[:, 4:8]), np.ascontiguousarray(heads[:, 8:12])
    if ros1:
        return sec.view("<u4").ravel().astype(np.float64) + nsec.view("<u4").ravel().astype(np.float64) * 1e-9
    little = (heads[:, 1] & 1).astype(bool)
    s = np.where(little, sec.view("<i4").ravel(), sec.view(">i4").ravel()).astype(np.float64)
    ns = np.where(little, nsec.view("<u4").ravel(), nsec.view(">u4").ravel()).astype(np.float64)
    return s + ns * 1e-9


def expand_paths(path: str | Path) -> list[Path]:
    """A path, or a glob pattern for split ROS 1 bags (sorted, so split order is kept)."""
    text = str(path)
    split = split_log_paths(text)  # "run_0.mcap,run_1.mcap": one recording in several files
    if split is not None:
        return [p for part in split for p in expand_paths(part)]
    if Path(text).name == "metadata.yaml":  # a ROS 2 bag given by its metadata file
        return [Path(text).parent]
    if not Path(text).exists() and any(ch in text for ch in "*?["):
        matches = sorted(glob.glob(text))
        if not matches:
            raise InputError(text, "no file matches this pattern")
        return [Path(m) for m in matches]
    return [Path(text)]
