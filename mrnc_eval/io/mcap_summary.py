"""An MCAP file's header profile and summary section read with struct, without the mcap library.

Why: a `slam` run on a ROS 2 MCAP file reads both only to open it (io/containers.py tells a ROS 2
file by its profile; io/ros2_mcap.py lists its channels and chunk indexes from the summary), and
importing the mcap library's reader for that (its record classes, its stream reader) and reading
through it costs ~10 ms CPU of the run's start. The records are read here as the MCAP format
defines them and as mcap's reader reads them: the footer at the end (opcode 2, summary start, summary
offset start, CRC, then the magic), and from the summary start every record up to the footer,
keeping Schema (3), Channel (4), ChunkIndex (8) and Statistics (11) records, each field in order,
strings as a uint32 length and UTF-8 bytes, maps as a uint32 byte length and their entries, bytes
past a record's known fields skipped. The result has the attributes of mcap's Summary and
records (tests/io/test_mcap_summary.py compares them on the project's logs).

Anything unusual (no magic, a length or offset outside the file, a summary start before the data
section, a record running past its section, text that is not UTF-8, no footer where it belongs, a
summary over 64 MiB) raises Unreadable: the caller then reads the file with a library, as before,
with its own checks and errors (io/ros2_mcap.py: rosbags' AnyReader, io/containers.py: mcap).
Every length is checked against the file before anything that size is read.
"""

from __future__ import annotations

import struct
from pathlib import Path
from types import SimpleNamespace
from typing import Any

MAGIC = b"\x89MCAP0\r\n"
_HEADER, _FOOTER, _SCHEMA, _CHANNEL, _CHUNK_INDEX, _STATISTICS = 0x01, 0x02, 0x03, 0x04, 0x08, 0x0B
_FOOTER_SIZE = 1 + 8 + 20  # opcode, length, summary start u64, summary offset start u64, CRC u32
_MAX_SUMMARY = 1 << 26  # bytes read at once; a summary is ~160 B a chunk (~8 MB for 50,000): beyond, mcap streams it


class Unreadable(Exception):
    """Not read here: the mcap library reads the file (and says what is wrong)."""


class _Fields:
    """Little-endian fields of one record's content, in order."""

    def __init__(self, data: bytes) -> None:
        self.data, self.pos = data, 0

    def num(self, fmt: str) -> int:
        (value,) = struct.unpack_from(fmt, self.data, self.pos)
        self.pos += struct.calcsize(fmt)
        return int(value)

    def raw(self, n: int) -> bytes:
        if self.pos + n > len(self.data):
            raise Unreadable("a field runs past its record")
        value = self.data[self.pos:self.pos + n]
        self.pos += n
        return value

    def text(self) -> str:
        return self.raw(self.num("<I")).decode()

    def pairs(self, key: str, value: str) -> dict[Any, Any]:
        """A map: its byte length, then key/value entries up to it ("s": a string)."""
        end = self.num("<I") + self.pos
        out: dict[Any, Any] = {}
        while self.pos < end:
            k = self.text() if key == "s" else self.num(key)
            out[k] = self.text() if value == "s" else self.num(value)
        if self.pos != end:  # the last entry runs past the map (rosbags refuses it: not whole entries)
            raise Unreadable("a map's entries run past its length")
        return out


def _schema(f: _Fields) -> SimpleNamespace:
    sid, name, encoding = f.num("<H"), f.text(), f.text()
    return SimpleNamespace(id=sid, name=name, encoding=encoding, data=f.raw(f.num("<I")))


def _channel(f: _Fields) -> SimpleNamespace:
    cid, schema_id, topic, encoding = f.num("<H"), f.num("<H"), f.text(), f.text()
    return SimpleNamespace(id=cid, schema_id=schema_id, topic=topic, message_encoding=encoding,
                           metadata=f.pairs("s", "s"))


def _chunk_index(f: _Fields) -> SimpleNamespace:
    start, end, offset, length = (f.num("<Q") for _ in range(4))
    offsets, index_length, compression = f.pairs("<H", "<Q"), f.num("<Q"), f.text()
    return SimpleNamespace(message_start_time=start, message_end_time=end, chunk_start_offset=offset,
                           chunk_length=length, message_index_offsets=offsets, message_index_length=index_length,
                           compression=compression, compressed_size=f.num("<Q"), uncompressed_size=f.num("<Q"))


def _statistics(f: _Fields) -> SimpleNamespace:
    names = ("message_count", "schema_count", "channel_count", "attachment_count", "metadata_count", "chunk_count",
             "message_start_time", "message_end_time")
    values = {n: f.num(fmt) for n, fmt in zip(names, ("<Q", "<H", "<I", "<I", "<I", "<I", "<Q", "<Q"), strict=True)}
    return SimpleNamespace(**values, channel_message_counts=f.pairs("<H", "<Q"))


def profile(path: Path) -> str:
    """The profile of the file's header record ("ros2" for a ROS 2 file)."""
    with path.open("rb") as fh:
        head = fh.read(8 + 9 + 4)
        if len(head) < 21 or head[:8] != MAGIC or head[8] != _HEADER:
            raise Unreadable("no MCAP header")
        (length, n) = struct.unpack_from("<QI", head, 9)
        if n + 4 > length or 17 + length > fh.seek(0, 2):  # checked before reading: n comes from the file
            raise Unreadable("the header ends early")
        fh.seek(21)
        text = fh.read(n)
    try:
        return text.decode()
    except UnicodeDecodeError as err:
        raise Unreadable(str(err)) from err


def read(path: Path) -> SimpleNamespace | None:
    """The summary (schemas and channels by id, statistics, chunk indexes in file order), None
    when the file has none, as mcap's reader gives it."""
    try:
        with path.open("rb") as fh:
            size = fh.seek(0, 2)
            fh.seek(max(0, size - _FOOTER_SIZE - 8))
            tail = fh.read()
            if len(tail) != _FOOTER_SIZE + 8 or tail[-8:] != MAGIC or tail[0] != _FOOTER:
                raise Unreadable("no MCAP footer")
            start = struct.unpack_from("<Q", tail, 9)[0]
            if start == 0:
                return None
            fh.seek(9)
            data_start = 17 + struct.unpack("<Q", fh.read(8))[0]  # after the header record, as rosbags checks
            if not data_start <= start <= size - _FOOTER_SIZE - 8:
                raise Unreadable("summary start outside the file")
            if size - 8 - start > _MAX_SUMMARY:
                raise Unreadable("a summary section this large is streamed by mcap")
            fh.seek(start)
            return _records(fh.read(size - 8 - start))
    except (struct.error, UnicodeDecodeError) as err:
        raise Unreadable(str(err)) from err


def _records(section: bytes) -> SimpleNamespace:
    summary = SimpleNamespace(schemas={}, channels={}, statistics=None, chunk_indexes=[], attachment_indexes=[],
                              metadata_indexes=[])
    pos = 0
    while True:
        if pos + 9 > len(section):
            raise Unreadable("the summary ends without its footer")
        opcode, length = struct.unpack_from("<BQ", section, pos)
        if pos + 9 + length > len(section):
            raise Unreadable("a summary record runs past the section")
        f = _Fields(section[pos + 9:pos + 9 + length])
        pos += 9 + length
        if opcode == _FOOTER:
            if pos != len(section):
                raise Unreadable("bytes after the footer")
            return summary
        if opcode == _SCHEMA:
            schema = _schema(f)
            summary.schemas[schema.id] = schema
        elif opcode == _CHANNEL:
            channel = _channel(f)
            summary.channels[channel.id] = channel
        elif opcode == _CHUNK_INDEX:
            summary.chunk_indexes.append(_chunk_index(f))
        elif opcode == _STATISTICS:
            summary.statistics = _statistics(f)
