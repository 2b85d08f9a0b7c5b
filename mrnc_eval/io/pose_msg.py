"""Pose messages straight from their serialised bytes, a batch at a time, with numpy.

rosbags' deserialiser builds each message object in Python (~40 us an Odometry message: 0.19 s
for a 30 s log's ground truth and wheel odometry). Odometry, PoseWithCovarianceStamped,
PoseStamped and TransformStamped are fixed-size apart from their strings (header.frame_id and
child_frame_id), so once each message's string lengths are read every number sits at a known
offset: one gather reads them all, whatever the string lengths. Little-endian CDR (ROS 2) and
ROS 1 serialisation are read here; anything else (big-endian CDR, bytes that do not parse as
one whole message of the type, text that is not UTF-8) gives None and the caller deserialises
with the library, which then raises its own error on bad bytes. For a well-formed message
the numbers are the library's to the bit (tests/io/test_pose_decode.py).

Layouts (offsets in bytes from the start of the serialised message):
  ROS 1: seq u32 @0, stamp sec u32 @4, nsec u32 @8, frame_id length u32 @12, its characters
         @16 (no terminator); child_frame_id (Odometry, TransformStamped) as length u32 and
         characters; then the float64s, packed with no alignment.
  CDR:   4-byte encapsulation header, stamp sec i32 @4, nanosec u32 @8, frame_id length u32
         @12 (with its NUL), characters @16; child_frame_id aligned to 4, the float64s aligned
         to 8 (alignment counted from byte 4); up to 3 bytes of padding may follow.
The float64s: position xyz, orientation xyzw first; Odometry then the pose covariance (36),
the twist (linear xyz, angular xyz) and its covariance (36); PoseWithCovarianceStamped the
pose covariance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# msgtype -> (has a child_frame_id string, number of float64s after the strings)
_LAYOUTS = {
    "nav_msgs/msg/Odometry": (True, 7 + 36 + 6 + 36),
    "geometry_msgs/msg/PoseWithCovarianceStamped": (False, 7 + 36),
    "geometry_msgs/msg/PoseStamped": (False, 7),
    "geometry_msgs/msg/TransformStamped": (True, 7),
}
_ODOM_TWIST = 7 + 36  # index of Odometry's twist.twist.linear.x among its float64s
_STRINGS_AT = 12  # frame_id's length field (ROS 1 and CDR)


@dataclass(frozen=True, kw_only=True)
class PoseBatch:
    """A batch of pose messages decoded at once."""

    stamps: np.ndarray  # (N,) header stamps, s
    position: np.ndarray  # (N, 3) m
    orientation: np.ndarray  # (N, 4) xyzw
    twist: np.ndarray | None  # (N, 6) Odometry's twist.twist: linear xyz m/s, angular xyz rad/s
    frame_id: str  # the last message's
    child_frame_id: str  # the last message's; "" for types without one


def decode_pose_batch(raws: list[bytes], msgtype: str, *, ros1: bool) -> PoseBatch | None:
    """All messages of the batch decoded at once, or None when they are not read here."""
    layout = _LAYOUTS.get(msgtype)
    if layout is None or not raws:
        return None
    has_child, n_doubles = layout
    joined = b"".join(raws)
    buf = np.frombuffer(joined, np.uint8)
    sizes = np.fromiter(map(len, raws), np.int64, len(raws))
    starts = np.concatenate(([0], np.cumsum(sizes)[:-1]))
    if np.any(sizes < _STRINGS_AT + 4) or (not ros1 and (np.any(buf[starts] != 0) or np.any(buf[starts + 1] != 1))):
        return None  # too short for a header, or not little-endian CDR
    frame_at = np.full(len(raws), _STRINGS_AT, np.int64)
    strings = _string(buf, starts, frame_at, sizes, ros1=ros1)
    if strings is None:
        return None
    child = _string(buf, starts, _aligned(strings[1], 4, ros1), sizes, ros1=ros1) if has_child else None
    if has_child and child is None:
        return None
    doubles_at = _aligned(child[1] if child is not None else strings[1], 8, ros1)
    padding = sizes - doubles_at - 8 * n_doubles
    if np.any(padding < 0) or np.any(padding > (0 if ros1 else 3)):
        return None  # not one whole message of the type
    texts = _texts(joined, starts, [strings, child], ros1=ros1)
    if texts is None:
        return None
    sec = _gather(buf, starts + 4, 4).view("<u4" if ros1 else "<i4").ravel().astype(np.float64)
    nsec = _gather(buf, starts + 8, 4).view("<u4").ravel().astype(np.float64)
    pose = _gather(buf, starts + doubles_at, 8 * 7).view("<f8")
    twist = _gather(buf, starts + doubles_at + 8 * _ODOM_TWIST, 8 * 6).view("<f8") if n_doubles > _ODOM_TWIST else None
    return PoseBatch(stamps=sec + nsec * 1e-9, position=pose[:, :3].copy(), orientation=pose[:, 3:].copy(),
                     twist=twist, frame_id=texts[0], child_frame_id=texts[1])


def _gather(buf: np.ndarray, at: np.ndarray, n: int) -> np.ndarray:
    """(N, n) bytes: n of them from each position `at` (a fresh array, viewable as any dtype)."""
    return buf[at[:, None] + np.arange(n)]


def _aligned(pos: np.ndarray, n: int, ros1: bool) -> np.ndarray:
    """Positions moved up to CDR's n-byte alignment, counted from byte 4 (ROS 1: unchanged)."""
    return pos if ros1 else pos + (-(pos - 4) % n)


def _string(buf: np.ndarray, starts: np.ndarray, at: np.ndarray, sizes: np.ndarray, *,
            ros1: bool) -> tuple[np.ndarray, np.ndarray] | None:
    """(where each message's string's text starts, where it ends) for the string whose length
    field sits at `at`; None when a length runs past its message (or, CDR, leaves out the NUL)."""
    if np.any(at + 4 > sizes):
        return None
    length = _gather(buf, starts + at, 4).view("<u4").ravel().astype(np.int64)
    if np.any(at + 4 + length > sizes) or (not ros1 and np.any(length == 0)):
        return None
    return at + 4, at + 4 + length


def _texts(joined: bytes, starts: np.ndarray, spans: list[tuple[np.ndarray, np.ndarray] | None], *,
           ros1: bool) -> tuple[str, str] | None:
    """The last message's frame_id and child_frame_id ("" without one), None unless every
    message's strings are UTF-8 (the library decodes them all). CDR's text leaves out the last
    byte its length counts (the NUL), as the library's does."""
    texts: list[str] = []
    for span in spans:
        if span is None:
            texts.append("")
            continue
        begin, end = (starts + span[0]).tolist(), (starts + span[1] - (0 if ros1 else 1)).tolist()
        try:
            for text in {joined[a:b] for a, b in zip(begin, end, strict=True)}:
                text.decode()
        except UnicodeDecodeError:
            return None
        texts.append(joined[begin[-1]:end[-1]].decode())
    return texts[0], texts[1]
