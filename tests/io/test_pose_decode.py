"""io/pose_msg.py's direct read of pose messages gives rosbags' numbers to the bit: on hand-made
messages (every pose type, ROS 1 and CDR, frame ids of every length modulo the alignments, UTF-8
beyond ASCII, covariances set), on the sample logs, and refuses (None, so the library reads and
reports) whatever is not one whole message of the type."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mrnc_eval.io import messages as M
from mrnc_eval.io import open_log
from mrnc_eval.io.pose_msg import PoseBatch, decode_pose_batch
from mrnc_eval.io.series import POSE_MSGTYPES
from mrnc_eval.io.typestore import typestore_for

SAMPLES = Path(__file__).resolve().parents[2] / "sample_logs"


def _message(ts: Any, msgtype: str, k: int, rng: np.random.Generator, ros1: bool) -> Any:
    """Message k of a batch: frame ids of k % 11 characters (one non-ASCII), random numbers."""
    frame, child = "fé"[: min(k % 11, 2)] + "x" * max(k % 11 - 2, 0), "c" * (k % 7)
    head = M.header(ts, 1.7e9 + k * 0.01 + rng.random() * 1e-3, frame, ros1, seq=k)
    pose = M.pose(ts, rng.normal(scale=100.0, size=3), rng.normal(size=4))
    cov = rng.normal(size=36)
    if msgtype == "geometry_msgs/msg/PoseStamped":
        return ts.types[msgtype](header=head, pose=pose)
    if msgtype == "geometry_msgs/msg/PoseWithCovarianceStamped":
        pwc = ts.types["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov)
        return ts.types[msgtype](header=head, pose=pwc)
    if msgtype == "geometry_msgs/msg/TransformStamped":
        tf = ts.types["geometry_msgs/msg/Transform"](translation=M.vector3(ts, rng.normal(size=3)),
                                                     rotation=M.quaternion(ts, rng.normal(size=4)))
        return ts.types[msgtype](header=head, child_frame_id=child, transform=tf)
    msg = M.odometry(ts, 0.0, frame, child, rng.normal(size=3), rng.normal(size=4), rng.normal(size=3),
                     rng.normal(size=3), ros1)
    msg.pose.covariance[:] = cov
    msg.twist.covariance[:] = rng.normal(size=36)
    msg.header = head
    return msg


def _serialised(ts: Any, msg: Any, msgtype: str, ros1: bool) -> bytes:
    return bytes(ts.serialize_ros1(msg, msgtype) if ros1 else ts.serialize_cdr(msg, msgtype))


def _librarys(ts: Any, raws: list[bytes], msgtype: str, ros1: bool) -> dict[str, Any]:
    """What the series read through rosbags: stamps, positions, orientations, twists, last frames."""
    msgs = [ts.deserialize_ros1(r, msgtype) if ros1 else ts.deserialize_cdr(r, msgtype) for r in raws]
    t = [float(m.header.stamp.sec) + float(m.header.stamp.nanosec) * 1e-9 for m in msgs]
    odom, tf = msgtype == "nav_msgs/msg/Odometry", msgtype == "geometry_msgs/msg/TransformStamped"
    poses = [m.transform if tf else m.pose.pose if odom or "Covariance" in msgtype else m.pose for m in msgs]
    p = [(x.translation if tf else x.position) for x in poses]
    q = [(x.rotation if tf else x.orientation) for x in poses]
    twist = [(m.twist.twist.linear, m.twist.twist.angular) for m in msgs] if odom else None
    return {"stamps": np.asarray(t), "position": np.asarray([(v.x, v.y, v.z) for v in p]),
            "orientation": np.asarray([(v.x, v.y, v.z, v.w) for v in q]),
            "twist": None if twist is None else np.asarray([(a.x, a.y, a.z, b.x, b.y, b.z) for a, b in twist]),
            "frame_id": msgs[-1].header.frame_id,
            "child_frame_id": msgs[-1].child_frame_id if odom or tf else ""}


def _assert_same(batch: PoseBatch | None, ref: dict[str, Any]) -> None:
    assert batch is not None
    for name, want in ref.items():
        got = getattr(batch, name)
        if isinstance(want, np.ndarray):
            assert got.dtype == want.dtype, name
            assert got.shape == want.shape, name
            assert got.tobytes() == want.tobytes(), name  # to the bit
        else:
            assert got == want, name


@pytest.mark.parametrize("ros1", [False, True])
@pytest.mark.parametrize("msgtype", POSE_MSGTYPES)
def test_pose_batch_equals_rosbags(msgtype: str, ros1: bool) -> None:
    ts, rng = typestore_for(ros1=ros1), np.random.default_rng(7)
    raws = [_serialised(ts, _message(ts, msgtype, k, rng, ros1), msgtype, ros1) for k in range(40)]
    assert len({len(r) for r in raws}) >= 2  # lengths vary, and with them the numbers' offsets
    for batch in (raws, raws[:1], raws[5:6], raws[::-1]):
        _assert_same(decode_pose_batch(batch, msgtype, ros1=ros1), _librarys(ts, batch, msgtype, ros1))


@pytest.mark.parametrize("ros1", [False, True])
def test_pose_batch_refuses_what_is_not_one_whole_message(ros1: bool) -> None:
    """Cut, lengthened, wrongly encapsulated or non-UTF-8 bytes: None (the library then reads and
    reports them); the same bytes beside good ones spoil the whole batch, never a wrong number."""
    msgtype = "nav_msgs/msg/Odometry"
    ts, rng = typestore_for(ros1=ros1), np.random.default_rng(3)
    good = [_serialised(ts, _message(ts, msgtype, k, rng, ros1), msgtype, ros1) for k in range(3, 6)]
    raw = good[0]
    bad = [raw[:-1], raw[:20], raw[:10], raw + b"\0" * 4, raw + b"\0" * 8]
    bad.append(raw[:16] + b"\xff" + raw[17:])  # frame_id "féx": its first character (ROS 1 and CDR)
    bad.append(raw[:12] + (10_000).to_bytes(4, "little") + raw[16:])  # a string longer than the message
    if not ros1:
        bad += [b"\0\0" + raw[2:], b"\1\1" + raw[2:]]  # big-endian, not CDR
    assert decode_pose_batch(good, msgtype, ros1=ros1) is not None
    for b in bad:
        assert decode_pose_batch([b], msgtype, ros1=ros1) is None
        assert decode_pose_batch([*good, b], msgtype, ros1=ros1) is None
    assert decode_pose_batch(good, "sensor_msgs/msg/Imu", ros1=ros1) is None
    if not ros1:  # CDR lets up to 3 bytes of padding follow, as the library does
        _assert_same(decode_pose_batch([raw + b"\0" * 3], msgtype, ros1=False),
                     _librarys(ts, [raw + b"\0" * 3], msgtype, False))


@pytest.mark.parametrize("name", ["circle_soft_ground.mcap", "loop_forest.bag"])
def test_sample_logs_poses_read_directly_equal_the_librarys(name: str) -> None:
    """Every pose topic of the sample logs (CDR in MCAP, ROS 1): read directly, the same arrays
    as through rosbags; the trajectories and wheel twists the series build from them too."""
    with open_log(SAMPLES / name) as lg:
        series = lg._series
        topics = [t for t, ch in lg.source.channels.items() if ch.msgtype in POSE_MSGTYPES]
        assert topics
        for topic in topics:
            ch = lg.source.channel(topic)
            raws = [bytes(r) for _t, r in lg.source.raw(topic)]
            ts = typestore_for(ros1=ch.encoding == "ros1")
            _assert_same(decode_pose_batch(raws, ch.msgtype, ros1=ch.encoding == "ros1"),
                         _librarys(ts, raws, ch.msgtype, ch.encoding == "ros1"))
            fast, slow = series._pose_batches(topic), series._pose_batches(topic, fast=False)
            for a, b in zip(fast, slow, strict=True):
                _assert_same(a, {k: getattr(b, k) for k in ("stamps", "position", "orientation", "twist",
                                                            "frame_id", "child_frame_id")})
