"""Copy the original log's topics, raw, into the exported MCAP (`export --with-log`).

Messages keep their bytes, their wire encoding and their record time; each topic keeps its
schema: the schema records of an MCAP log as they are, the message definitions stored in a
ROS 1 bag (ros1msg) or regenerated from the typestore for ROS 2 bags (ros2msg, CDR), which
is what Foxglove needs to decode them."""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from mcap.writer import Writer

from mrnc_eval.errors import InputError
from mrnc_eval.io.containers import describe_error, detect_container, openable
from mrnc_eval.io.library_errors import data_errors


def copy_log(writer: Writer, log_path: Path, reserved_prefix: str) -> Counter[str]:
    """Every topic of `log_path` into the mcap `writer`; returns the messages copied per topic.
    A topic under `reserved_prefix` (ours) would be ambiguous: refused."""
    container = detect_container([log_path])
    try:
        if container in ("mcap", "ros2-mcap") and log_path.is_file():
            return _copy_mcap(writer, log_path, reserved_prefix)
        return _copy_rosbags(writer, log_path, container, reserved_prefix)
    except InputError:
        raise
    except data_errors() as err:
        raise InputError(log_path, f"cannot copy the log's topics: {describe_error(err)}") from err


def _check_topic(log_path: Path, topic: str, reserved_prefix: str) -> None:
    if topic == reserved_prefix or topic.startswith(reserved_prefix + "/"):
        raise InputError(log_path, f"the log uses our export namespace {reserved_prefix}/", topic=topic)


def _copy_mcap(writer: Writer, log_path: Path, reserved_prefix: str) -> Counter[str]:
    from mcap.reader import make_reader

    counts: Counter[str] = Counter()
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    with log_path.open("rb") as fh:
        for schema, channel, message in make_reader(fh).iter_messages(log_time_order=True):
            if channel.id not in channel_ids:
                _check_topic(log_path, channel.topic, reserved_prefix)
                sid = 0
                if schema is not None:
                    if schema.id not in schema_ids:
                        schema_ids[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
                    sid = schema_ids[schema.id]
                channel_ids[channel.id] = writer.register_channel(channel.topic, channel.message_encoding, sid,
                                                                  dict(channel.metadata))
            writer.add_message(channel_ids[channel.id], log_time=message.log_time, data=message.data,
                               publish_time=message.publish_time, sequence=message.sequence)
            counts[channel.topic] += 1
    return counts


def _copy_rosbags(writer: Writer, log_path: Path, container: str, reserved_prefix: str) -> Counter[str]:
    from rosbags.highlevel import AnyReader

    from mrnc_eval.io.typestore import typestore_for

    counts: Counter[str] = Counter()
    ros1 = container == "ros1"
    with openable([log_path], container) as named, \
            AnyReader(named, default_typestore=typestore_for(ros1=ros1)) as reader:
        store = reader.typestore
        channel_ids: dict[int, int] = {}
        schema_ids: dict[str, int] = {}
        for conn in reader.connections:
            _check_topic(log_path, conn.topic, reserved_prefix)
            if ros1:
                name, enc, msg_enc = conn.msgtype.replace("/msg/", "/"), "ros1msg", "ros1"
                text = store.generate_msgdef(conn.msgtype, ros_version=1)[0]
            else:
                name, enc, msg_enc = conn.msgtype, "ros2msg", "cdr"
                text = store.generate_msgdef(conn.msgtype, ros_version=2)[0]
            if name not in schema_ids:
                schema_ids[name] = writer.register_schema(name, enc, text.encode())
            channel_ids[conn.id] = writer.register_channel(conn.topic, msg_enc, schema_ids[name], {})
        for conn, t_rec, raw in reader.messages():
            writer.add_message(channel_ids[conn.id], log_time=t_rec, data=bytes(raw), publish_time=t_rec,
                               sequence=counts[conn.topic])
            counts[conn.topic] += 1
    return counts
