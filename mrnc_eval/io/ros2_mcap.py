"""A single ROS 2 MCAP file opened from its summary, without rosbags' AnyReader.

Why: opening one with AnyReader imports rosbags' bag readers (rosbag1, rosbag2 and their storage
plugins: ~32 ms CPU of imports, of a 0.7 s `slam` run) and reads the summary a second time, while
a single MCAP file's overview, first messages and sweeps are read from its indexes anyway
(io/mcap_index.py, io/mcap_stream.py). What AnyReader gives such a file is made here the same way:
the channels (topic, type from the schema name, count from the statistics, encoding) and one
typestore of every channel's definition, parsed and registered in the channels' order with rosbags'
own parsers, so the same messages decode to the same objects (tests/io/test_ros2_mcap.py;
NavSatFix, TFMessage and JointState to objects alike, read by io/small_msgs.py). When every schema
is plainly written (io/msg_text.py reads it: then rosbags' grammar accepts it too), that typestore
is made only when a message is first decoded through rosbags, which a `slam` run never does: it
imports no part of rosbags (~30 ms of parsing, registering and importing saved). A full read of
messages (`messages`), the fallback when the indexes cannot be used, opens the AnyReader source then.

Only a plainly well-formed file takes this path: a ros2 profile, a summary with statistics and
schemas, every channel CDR with a ros2msg/ros2idl schema whose type its definition declares.
Anything else (`NotPlain`) is opened by AnyReader as before, with its own checks and errors.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

from mrnc_eval.io import mcap_summary, msg_text, small_msgs
from mrnc_eval.io.chunk_prefix import IndexUnusable
from mrnc_eval.io.sources import Channel, RosbagsSource

_IDL_SEPARATOR = "=" * 80 + "\n"  # several IDL definitions in one schema, each after "IDL: name"


class NotPlain(Exception):
    """The file needs AnyReader's own opening (its checks and its errors)."""


def _types_of(schema: Any, msgtype: str) -> dict[str, Any]:
    """rosbags' field definitions of one schema, parsed as AnyReader parses a connection's."""
    from rosbags.typesys import get_types_from_idl, get_types_from_msg

    text = schema.data.decode()
    if schema.encoding == "ros2msg":
        return dict(get_types_from_msg(text, msgtype))
    types: dict[str, Any] = {}
    if not text.startswith(f"{_IDL_SEPARATOR}IDL: "):
        return dict(get_types_from_idl(text))
    for part in text.split(_IDL_SEPARATOR)[1:]:
        head, idl = part.split("\n", 1)
        if not head.startswith("IDL: "):
            raise NotPlain("an IDL schema part without its name")
        types.update(get_types_from_idl(idl))
    return types


def read_summary(path: Path) -> Any:
    """The file's mcap summary, if it is plainly a ROS 2 MCAP file (see the module's docstring),
    read without the mcap library (io/mcap_summary.py); NotPlain when it cannot be read so."""
    try:
        if mcap_summary.profile(path) != "ros2":
            raise NotPlain("profile is not ros2")
        summary = mcap_summary.read(path)
    except mcap_summary.Unreadable as err:  # AnyReader's checks then (mcap's reader accepts some it refuses)
        raise NotPlain(str(err)) from err
    if summary is None or summary.statistics is None or not summary.schemas or not summary.channels:
        raise NotPlain("no summary, statistics or schemas")
    for ch in summary.channels.values():
        schema = summary.schemas.get(ch.schema_id)
        if ch.message_encoding != "cdr" or schema is None or schema.encoding not in ("ros2msg", "ros2idl"):
            raise NotPlain(f"channel {ch.topic}: not CDR with a ROS 2 schema")
    return summary


class Ros2McapSource:
    """RosbagsSource's interface for one plainly well-formed ROS 2 MCAP file (`summary`: its
    read_summary, kept for the chunk indexes)."""

    def __init__(self, path: Path, summary: Any) -> None:
        self.path = path
        self.summary = summary
        self._store: Any = None  # rosbags' typestore of every schema, made when first needed
        self._defined = msg_text.definitions(summary)  # None: rosbags parses the schemas now
        types = self._defined if self._defined is not None else self._typestore().fielddefs
        counts = summary.statistics.channel_message_counts
        self.channels: dict[str, Channel] = {}
        for cid, ch in summary.channels.items():
            msgtype = summary.schemas[ch.schema_id].name
            if msgtype not in types:
                raise NotPlain(f"{msgtype}: not in its own definition")
            known = self.channels.get(ch.topic)
            if known is not None:  # one topic on several channels: AnyReader counts them all, keeps the first type
                self.channels[ch.topic] = Channel(ch.topic, known.msgtype, known.count + int(counts.get(cid, 0)), "cdr")
            else:
                self.channels[ch.topic] = Channel(ch.topic, msgtype, int(counts.get(cid, 0)), "cdr")
        self._full: RosbagsSource | None = None
        self._standard: dict[str, bool] = {}  # msgtype -> defined as io/small_msgs.py reads it

    def _typestore(self) -> Any:
        """rosbags' typestore of every channel's schema, as AnyReader makes it (made once)."""
        if self._store is None:
            from rosbags.typesys import Stores, get_typestore

            types: dict[str, Any] = {}
            parsed: dict[int, dict[str, Any]] = {}  # AnyReader parses a schema per channel: the same types
            for ch in self.summary.channels.values():
                if ch.schema_id not in parsed:
                    schema = self.summary.schemas[ch.schema_id]
                    parsed[ch.schema_id] = _types_of(schema, schema.name)
                types.update(parsed[ch.schema_id])
            store = get_typestore(Stores.EMPTY)
            store.register(types)
            self._store = store
        return self._store

    def messages(self, topics: list[str]) -> Iterator[tuple[str, int, bytes]]:
        """Every message of `topics` in log order, through AnyReader (opened on first use)."""
        if self._full is None:
            self._full = RosbagsSource([self.path], ros1=False)
        return self._full.messages(topics)

    def indexed_overview(self, topics: list[str], wants: dict[str, int]) -> Iterator[tuple[str, int, bytes]]:
        raise IndexUnusable("not a ROS 1 bag")

    def deserialize(self, raw: bytes, topic: str) -> Any:  # a rosbags message object, or one alike
        msgtype = self.channels[topic].msgtype
        if msgtype not in self._standard:
            self._standard[msgtype] = (small_msgs.standard_in(self._defined, msgtype) if self._defined is not None
                                       else small_msgs.standard(self._typestore().fielddefs, msgtype))
        msg = small_msgs.decode(raw, msgtype) if self._standard[msgtype] else None
        return msg if msg is not None else self._library_deserialize(raw, msgtype)

    def _library_deserialize(self, raw: bytes, msgtype: str) -> Any:
        from rosbags.serde import SerdeError

        try:
            return self._typestore().deserialize_cdr(raw, msgtype)
        except SerdeError as err:  # as AnyReader reports it
            from rosbags.highlevel import AnyReaderError

            raise AnyReaderError(*err.args) from None

    def close(self) -> None:
        if self._full is not None:
            self._full.close()
