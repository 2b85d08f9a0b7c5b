"""sensor_msgs/PointCloud2 read straight from its serialised bytes, its point data a view.

rosbags' deserialiser builds the whole message object (~0.9 ms a 6.3 MB OS0-128 cloud); the
cloud needs only its few scalar fields, the field list and a view of `data`. Little-endian CDR
(ROS 2) and ROS 1 serialisation are read here; anything else, or bytes that do not parse as one
whole PointCloud2 message, give None and the caller deserialises with the library, which then
raises its own error on bad bytes. For a well-formed message the result equals the library's
field for field (tests/io/test_cloud_decode.py).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

_U32 = struct.Struct("<I")
_FIELD_TAIL_CDR = struct.Struct("<IB3xI")  # offset u32, datatype u8, (pad to 4), count u32
_FIELD_TAIL_ROS1 = struct.Struct("<IBI")  # packed: offset u32, datatype u8, count u32
_MAX_FIELDS = 1024  # a longer field list is not a point cloud's: left to the library


@dataclass(frozen=True, kw_only=True)
class Stamp:
    """A header stamp (sec, nanosec)."""

    sec: int
    nanosec: int


@dataclass(frozen=True, kw_only=True)
class Header:
    """A cloud message's header."""

    stamp: Stamp
    frame_id: str


@dataclass(frozen=True, kw_only=True)
class Field:
    """One PointField of a cloud message."""

    name: str
    offset: int
    datatype: int
    count: int


@dataclass(frozen=True, kw_only=True)
class CloudMessage:
    """The PointCloud2 fields decode_cloud reads (names as in the message definition)."""

    header: Header
    height: int
    width: int
    fields: list[Field]
    is_bigendian: bool
    point_step: int
    row_step: int
    data: np.ndarray  # uint8 view into the serialised message
    is_dense: bool


def parse_cloud(raw: bytes | memoryview, *, ros1: bool) -> CloudMessage | None:
    """The cloud of one serialised PointCloud2 message, or None when it is not read here."""
    try:
        return _parse_ros1(raw) if ros1 else _parse_cdr(raw)
    except (struct.error, IndexError, UnicodeDecodeError, ValueError):
        return None


class _Cursor:
    """A read position in a serialised message; `base` is where CDR alignment counts from."""

    def __init__(self, buf: bytes | memoryview, pos: int, *, base: int, cdr: bool) -> None:
        self.buf, self.pos, self.base, self.cdr = buf, pos, base, cdr

    def align(self, n: int) -> None:
        if self.cdr:
            self.pos += -(self.pos - self.base) % n

    def u32(self) -> int:
        self.align(4)
        (value,) = _U32.unpack_from(self.buf, self.pos)
        self.pos += 4
        return int(value)

    def u8(self) -> int:
        value = self.buf[self.pos]
        self.pos += 1
        return int(value)

    def string(self) -> str:
        """CDR: length with the terminating NUL, which is dropped; ROS 1: length without one."""
        n = self.u32()
        end = self.pos + n
        if end > len(self.buf) or (self.cdr and (n == 0 or self.buf[end - 1] != 0)):
            raise ValueError("bad string")
        text = bytes(self.buf[self.pos:end - 1 if self.cdr else end]).decode("utf-8")
        self.pos = end
        return text

    def field(self) -> Field:
        name = self.string()
        self.align(4)
        tail = _FIELD_TAIL_CDR if self.cdr else _FIELD_TAIL_ROS1
        offset, datatype, count = tail.unpack_from(self.buf, self.pos)
        self.pos += tail.size
        return Field(name=name, offset=offset, datatype=datatype, count=count)


def _parse_cdr(raw: bytes | memoryview) -> CloudMessage | None:
    if len(raw) < 4 or raw[0] != 0 or raw[1] != 1:  # little-endian CDR only
        return None
    cur = _Cursor(raw, 4, base=4, cdr=True)
    sec, nanosec = struct.unpack_from("<iI", raw, 4)
    cur.pos = 12
    return _body(cur, Header(stamp=Stamp(sec=sec, nanosec=nanosec), frame_id=cur.string()))


def _parse_ros1(raw: bytes | memoryview) -> CloudMessage | None:
    _seq, sec, nsec = struct.unpack_from("<III", raw, 0)
    cur = _Cursor(raw, 12, base=0, cdr=False)
    return _body(cur, Header(stamp=Stamp(sec=sec, nanosec=nsec), frame_id=cur.string()))


def _body(cur: _Cursor, header: Header) -> CloudMessage | None:
    """Everything after the header; None unless the bytes end exactly after is_dense."""
    height, width, n_fields = cur.u32(), cur.u32(), cur.u32()
    if n_fields > _MAX_FIELDS:
        return None
    fields = [cur.field() for _ in range(n_fields)]
    is_bigendian = cur.u8()
    point_step, row_step, n_data = cur.u32(), cur.u32(), cur.u32()
    if cur.pos + n_data + 1 > len(cur.buf):
        return None
    data = np.frombuffer(cur.buf, np.uint8, n_data, cur.pos)
    cur.pos += n_data
    is_dense = cur.u8()
    padding = len(cur.buf) - cur.pos  # CDR may pad the message to a multiple of 4 bytes
    if not 0 <= padding <= (3 if cur.cdr else 0) or is_bigendian > 1 or is_dense > 1:
        return None
    return CloudMessage(header=header, height=height, width=width, fields=fields, is_bigendian=bool(is_bigendian),
                        point_step=point_step, row_step=row_step, data=data, is_dense=bool(is_dense))
