"""Raw message sources behind LogReader: one per container family.

A source lists its channels (topic, message type, count, wire encoding) and yields raw
serialised messages with their record time; it deserialises on request. Two exist:

- `RosbagsSource`: ROS 1 bags (one or several split files), ROS 2 bag directories,
  single .db3 and ROS 2 .mcap files, through rosbags' AnyReader. Types come from the
  definitions stored in the log; when a log stores none (ROS 2 Humble sqlite3 bags do
  not), from rosbags' ROS 2 Humble / ROS 1 Noetic typestores.
- `McapSource`: any other MCAP file, through the mcap library. Channels encoded as ROS 2
  CDR (ros2msg/ros2idl schemas) or ROS 1 (ros1msg schemas) are decoded with rosbags'
  deserialisers; any other encoding (json, protobuf, flatbuffer...) is listed but
  refused with a clear error when its topic is read.

Library exceptions are left to LogReader, which turns them into InputError.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mrnc_eval.errors import InputError
from mrnc_eval.io.chunk_prefix import IndexUnusable
from mrnc_eval.io.library_errors import data_errors


@dataclass(frozen=True)
class Channel:
    """One topic of a log as its container lists it."""

    topic: str
    msgtype: str  # ROS 2 style, pkg/msg/Name
    count: int  # from the container's index (-1: unknown); LogReader recounts while scanning
    encoding: str  # "ros1" | "cdr" | anything else (undecodable)
    problem: str | None = None  # why this topic cannot be decoded, if it cannot


def normalize_msgtype(name: str) -> str:
    """ROS 1 style pkg/Name -> pkg/msg/Name (ROS 2 names pass through)."""
    parts = name.strip("/").split("/")
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return "/".join(parts)


def _unknown_type(msgtype: str) -> str:
    return (f"unknown message type {msgtype} (the log stores no definition and it is not a standard "
            "ROS 2 Humble / ROS 1 Noetic type)")


class RosbagsSource:
    def __init__(self, paths: list[Path], ros1: bool) -> None:
        from rosbags.highlevel import AnyReader

        from mrnc_eval.io.typestore import LazyTypestore

        default: Any = LazyTypestore(ros1=ros1)  # AnyReader reads its fielddefs only for a log lacking definitions
        self.ros1 = ros1
        self.paths = paths
        self._reader = AnyReader(paths, default_typestore=default)
        try:
            self._reader.open()
        except data_errors() as err:
            if ros1 and "index" in str(err).lower():  # a recording cut short: its index (written last) is gone
                raise InputError(",".join(str(p) for p in paths), f"the bag's index is damaged or missing, as when a "
                                 f"recording is cut short ({err}); rebuild it with `rosbag reindex` (ROS 1) on a "
                                 "copy, then read the copy") from err
            raise
        self._add_missing_types(default)
        known = self._reader.typestore.fielddefs
        self._conns: dict[str, list[Any]] = {}
        for c in self._reader.connections:
            self._conns.setdefault(c.topic, []).append(c)
        self.channels: dict[str, Channel] = {}
        for topic, conns in self._conns.items():
            msgtype = conns[0].msgtype
            fmt = "ros1" if ros1 else conns[0].ext.serialization_format
            problem = None
            if fmt not in ("ros1", "cdr"):
                problem = f"serialization format {fmt!r} is not supported (only cdr)"
            elif msgtype not in known:
                problem = _unknown_type(msgtype)
            self.channels[topic] = Channel(topic, msgtype, sum(c.msgcount for c in conns), fmt, problem)

    def _add_missing_types(self, default: Any) -> None:
        """Logs that define some types but not others: take the rest from the standard store."""
        store = self._reader.typestore
        missing = {c.msgtype for c in self._reader.connections} - set(store.fielddefs)
        if not missing:
            return
        extra = {name: defs for name, defs in default.fielddefs.items() if name not in store.fielddefs}
        if extra:
            store.register(extra)

    def messages(self, topics: list[str]) -> Iterator[tuple[str, int, bytes]]:
        conns = [c for t in topics for c in self._conns[t]]
        try:
            for conn, t_rec, raw in self._reader.messages(connections=conns):
                yield conn.topic, t_rec, raw
        except data_errors() as err:
            if not _is_chunk_damage(err):
                raise
            raise InputError(",".join(str(p) for p in self.paths), f"a chunk is damaged: {err}; its messages "
                             "cannot be trusted (mrnc-eval info lists the damaged chunks)") from None

    def indexed_overview(self, topics: list[str], wants: dict[str, int]) -> Iterator[tuple[str, int, bytes]]:
        """`messages(topics)` with each message cut to wants[topic] bytes (io/bag_index.py), for
        ROS 1 bags; IndexUnusable otherwise."""
        from mrnc_eval.io.bag_index import overview

        if not self.ros1:
            raise IndexUnusable("not a ROS 1 bag")
        return overview([(t, c) for t in topics for c in self._conns[t]], wants)

    def deserialize(self, raw: bytes, topic: str) -> Any:  # a rosbags message object
        return self._reader.deserialize(raw, self.channels[topic].msgtype)

    def close(self) -> None:
        self._reader.close()


def _is_chunk_damage(err: BaseException) -> bool:
    """A reader's or decompressor's complaint that a chunk is not what was written (its CRC or
    size disagrees, the compressed bytes do not decode)."""
    text = str(err).lower()
    kind = f"{type(err).__module__}.{type(err).__name__}".lower()
    return "checksum mismatch" in text or "size mismatch" in text or "crc" in kind or "zstd" in kind \
        or "lz4" in kind


class McapSource:
    def __init__(self, path: Path) -> None:
        from mcap.reader import make_reader
        from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

        self.path = path
        self._fh = path.open("rb")
        try:
            self._reader = make_reader(self._fh, validate_crcs=True)  # a damaged chunk is an error, never data
            summary = self._reader.get_summary()
        except BaseException:
            self._fh.close()
            raise
        if summary is None:
            self._fh.close()
            raise InputError(path, "MCAP file has no summary section (truncated or still being written?)")
        self._stores = {"ros1": get_typestore(Stores.EMPTY), "cdr": get_typestore(Stores.EMPTY)}
        counts = summary.statistics.channel_message_counts if summary.statistics else None
        self.channels: dict[str, Channel] = {}
        for cid, ch in summary.channels.items():
            schema = summary.schemas.get(ch.schema_id)
            schema_enc = schema.encoding if schema else ""
            msgtype = normalize_msgtype(schema.name) if schema else ""
            problem = None
            if schema is not None and ch.message_encoding == "cdr" and schema_enc in ("ros2msg", "ros2idl"):
                text = schema.data.decode("utf-8", errors="replace")
                types = get_types_from_msg(text, msgtype) if schema_enc == "ros2msg" else get_types_from_idl(text)
                self._register(self._stores["cdr"], types)
            elif schema is not None and ch.message_encoding == "ros1" and schema_enc == "ros1msg":
                text = schema.data.decode("utf-8", errors="replace")
                self._register(self._stores["ros1"], get_types_from_msg(text, msgtype))
            else:
                problem = (f"message encoding {ch.message_encoding!r} (schema {schema_enc or 'none'!r}) is not "
                           "supported; only ROS 1 and ROS 2 (CDR) messages can be decoded")
            count = int(counts.get(cid, 0)) if counts is not None else -1  # -1: no statistics record
            self.channels[ch.topic] = Channel(ch.topic, msgtype or f"<{ch.message_encoding}>",
                                              count, ch.message_encoding, problem)

    @staticmethod
    def _register(store: Any, types: dict[str, Any]) -> None:
        store.register({k: v for k, v in types.items() if k not in store.fielddefs})

    def messages(self, topics: list[str]) -> Iterator[tuple[str, int, bytes]]:
        from mcap.stream_reader import CRCValidationError

        try:
            for _schema, channel, message in self._reader.iter_messages(topics=topics, log_time_order=True):
                yield channel.topic, int(message.log_time), message.data
        except CRCValidationError as err:
            chunk = getattr(err, "record", None)
            when = (f" (messages {chunk.message_start_time / 1e9:.3f}-{chunk.message_end_time / 1e9:.3f} s)"
                    if chunk is not None else "")
            raise InputError(self.path, f"a chunk{when} is damaged: CRC mismatch; its messages cannot be "
                             "trusted (mrnc-eval info lists the damaged chunks)") from None
        except data_errors() as err:  # the decompressor's complaint about a damaged chunk
            if isinstance(err, InputError) or not _is_chunk_damage(err):
                raise
            raise InputError(self.path, f"a chunk is damaged: it does not decompress ({err}); "
                             "mrnc-eval info lists the damaged chunks") from None

    def deserialize(self, raw: bytes, topic: str) -> Any:  # a rosbags message object
        ch = self.channels[topic]
        store = self._stores[ch.encoding]
        if ch.encoding == "ros1":
            return store.deserialize_ros1(raw, ch.msgtype)
        return store.deserialize_cdr(raw, ch.msgtype)

    def close(self) -> None:
        self._fh.close()
