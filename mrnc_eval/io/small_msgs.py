"""NavSatFix, TFMessage and JointState read straight from little-endian CDR bytes.

Why: rosbags generates and compiles the (de)serialisers of a type and of every type it holds the
first time one of its messages is decoded: ~6 ms for TFMessage, ~3 ms each for NavSatFix and
JointState, for the one /tf_static message, the fixes and the first JointState messages a `slam`
run decodes (~13 ms of its start). These three are small and fixed in shape, so they are read here
with struct, into objects with the attributes rosbags' messages have (header.stamp.sec, ...,
arrays as numpy float64), and the same values to the bit (tests/io/test_small_msgs.py).

CDR as rosbags reads it: a 4-byte encapsulation header (0, 1: little endian; anything else is left
to rosbags), then each number aligned to its size counted from byte 4; a string is a uint32 length
counting a closing NUL, then its bytes; a sequence a uint32 count, its float64s aligned to 8 only
when there is one; up to 3 bytes of padding may follow the message. Bytes that do not read as one
whole message (short, a string without its NUL, not UTF-8, more padding) give None: the caller
then asks rosbags, which raises its own error. Only for a log whose definitions of these types
are the standard ones (`standard`); any other definition is rosbags' to read.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import numpy as np

_BASE, _NAME, _ARRAY, _SEQUENCE = 1, 2, 3, 4  # rosbags' Nodetype values in its field definitions

# each field as "type" (a base type or a message type), "type[n]" (fixed array) or "type[]" (sequence)
_STANDARD: dict[str, tuple[tuple[str, str], ...]] = {
    "builtin_interfaces/msg/Time": (("sec", "int32"), ("nanosec", "uint32")),
    "std_msgs/msg/Header": (("stamp", "builtin_interfaces/msg/Time"), ("frame_id", "string")),
    "sensor_msgs/msg/NavSatStatus": (("status", "int8"), ("service", "uint16")),
    "sensor_msgs/msg/NavSatFix": (("header", "std_msgs/msg/Header"), ("status", "sensor_msgs/msg/NavSatStatus"),
                                  ("latitude", "float64"), ("longitude", "float64"), ("altitude", "float64"),
                                  ("position_covariance", "float64[9]"), ("position_covariance_type", "uint8")),
    "geometry_msgs/msg/Vector3": (("x", "float64"), ("y", "float64"), ("z", "float64")),
    "geometry_msgs/msg/Quaternion": (("x", "float64"), ("y", "float64"), ("z", "float64"), ("w", "float64")),
    "geometry_msgs/msg/Transform": (("translation", "geometry_msgs/msg/Vector3"),
                                    ("rotation", "geometry_msgs/msg/Quaternion")),
    "geometry_msgs/msg/TransformStamped": (("header", "std_msgs/msg/Header"), ("child_frame_id", "string"),
                                           ("transform", "geometry_msgs/msg/Transform")),
    "tf2_msgs/msg/TFMessage": (("transforms", "geometry_msgs/msg/TransformStamped[]"),),
    "sensor_msgs/msg/JointState": (("header", "std_msgs/msg/Header"), ("name", "string[]"),
                                   ("position", "float64[]"), ("velocity", "float64[]"), ("effort", "float64[]")),
}


class _Bad(Exception):
    """Not one whole message of the type: rosbags reads it (and says what is wrong)."""


def _field_type(desc: Any) -> str:
    """A rosbags field description in _STANDARD's notation ("?" for anything else)."""
    kind, info = int(desc[0]), desc[1]
    if kind == _BASE:
        return str(info[0]) if info[1] == 0 else "?"  # a bounded string is not the standard
    if kind == _NAME:
        return str(info)
    if kind in (_ARRAY, _SEQUENCE):
        inner = _field_type(info[0])
        return f"{inner}[{info[1]}]" if kind == _ARRAY else (f"{inner}[]" if info[1] == 0 else "?")
    return "?"


def standard(fielddefs: Any, msgtype: str) -> bool:
    """Whether the log defines `msgtype` and every type it holds as _STANDARD does (rosbags'
    fielddefs: name -> (constants, [(field, description)]))."""
    return standard_in({name: tuple((str(f), _field_type(d)) for f, d in fielddefs[name][1])
                        for name in fielddefs}, msgtype)


def standard_in(defined: dict[str, tuple[tuple[str, str], ...]], msgtype: str) -> bool:
    """`standard` on definitions in _STANDARD's notation (type -> ((field, type), ...))."""
    if msgtype not in _DECODERS:
        return False
    todo, seen = [msgtype], set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        if name not in _STANDARD or defined.get(name) != _STANDARD[name]:
            return False
        todo += [t.split("[")[0] for _, t in _STANDARD[name] if "/" in t]
    return True


class _Cdr:
    """A read position in one little-endian CDR message."""

    def __init__(self, raw: bytes | memoryview) -> None:
        self.raw, self.pos = raw, 4

    def num(self, fmt: str) -> Any:
        size = struct.calcsize(fmt)
        self.pos += -(self.pos - 4) % size
        (value,) = struct.unpack_from(fmt, self.raw, self.pos)
        self.pos += size
        return value

    def string(self) -> str:
        n = self.num("<I")
        end = self.pos + n
        if n < 1 or end > len(self.raw) or self.raw[end - 1] != 0:
            raise _Bad
        text = bytes(self.raw[self.pos:end - 1]).decode()
        self.pos = end
        return text

    def doubles(self, n: int) -> np.ndarray:
        if n:
            self.pos += -(self.pos - 4) % 8
        if self.pos + 8 * n > len(self.raw):
            raise _Bad
        values = np.frombuffer(self.raw, np.float64, n, self.pos)
        self.pos += 8 * n
        return values

    def header(self) -> SimpleNamespace:
        stamp = SimpleNamespace(sec=self.num("<i"), nanosec=self.num("<I"))
        return SimpleNamespace(stamp=stamp, frame_id=self.string())

    def xyz(self, names: str) -> SimpleNamespace:
        return SimpleNamespace(**{c: self.num("<d") for c in names})


def _navsatfix(r: _Cdr) -> SimpleNamespace:
    header = r.header()
    status = SimpleNamespace(status=r.num("<b"), service=r.num("<H"))
    lat, lon, alt = r.num("<d"), r.num("<d"), r.num("<d")
    return SimpleNamespace(header=header, status=status, latitude=lat, longitude=lon, altitude=alt,
                           position_covariance=r.doubles(9), position_covariance_type=r.num("<B"))


def _tf_message(r: _Cdr) -> SimpleNamespace:
    transforms = []
    for _ in range(r.num("<I")):
        header, child = r.header(), r.string()
        transform = SimpleNamespace(translation=r.xyz("xyz"), rotation=r.xyz("xyzw"))
        transforms.append(SimpleNamespace(header=header, child_frame_id=child, transform=transform))
    return SimpleNamespace(transforms=transforms)


def _joint_state(r: _Cdr) -> SimpleNamespace:
    header = r.header()
    names = [r.string() for _ in range(r.num("<I"))]
    position, velocity, effort = (r.doubles(r.num("<I")) for _ in range(3))
    return SimpleNamespace(header=header, name=names, position=position, velocity=velocity, effort=effort)


_DECODERS: dict[str, Callable[[_Cdr], SimpleNamespace]] = {
    "sensor_msgs/msg/NavSatFix": _navsatfix, "tf2_msgs/msg/TFMessage": _tf_message,
    "sensor_msgs/msg/JointState": _joint_state,
}


def decode(raw: bytes | memoryview, msgtype: str) -> SimpleNamespace | None:
    """The message, or None when it is not read here (another type, not little-endian CDR, bytes
    that are not one whole message). Only for a log whose definitions are `standard`."""
    decoder = _DECODERS.get(msgtype)
    if decoder is None or len(raw) < 4 or raw[0] != 0 or raw[1] != 1:
        return None
    r = _Cdr(raw)
    try:
        msg = decoder(r)
    except (_Bad, struct.error, UnicodeDecodeError):
        return None
    return msg if len(raw) - r.pos <= 3 else None
