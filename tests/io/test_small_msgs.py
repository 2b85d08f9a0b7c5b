"""NavSatFix, TFMessage and JointState read from CDR bytes (io/small_msgs.py) against rosbags'
deserialiser: the same values to the bit for every string length (each alignment), sequence
length and number, including the empty ones; None for what rosbags would refuse or reads otherwise
(big endian, short, a string without its NUL, not UTF-8, too much padding); a definition that is
not the standard one is never read here."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pytest

from mrnc_eval.io import messages as M
from mrnc_eval.io import small_msgs
from mrnc_eval.io.typestore import typestore_for
from tests.io.test_ros2_mcap import _same

TS = typestore_for(ros1=False)
FIX, TF, JOINTS = "sensor_msgs/msg/NavSatFix", "tf2_msgs/msg/TFMessage", "sensor_msgs/msg/JointState"
RNG = np.random.default_rng(7)


def _fix(frame: str, t: float) -> Any:
    cov = RNG.normal(size=9)
    cov[4] = -0.0
    return M.navsatfix(TS, t, frame, RNG.normal(size=3) * [40, 100, 300], cov, int(RNG.integers(-1, 3)), ros1=False)


def _tf(frames: list[tuple[str, str]], t: float) -> Any:
    mats = []
    for _ in frames:
        m = np.eye(4)
        m[:3, 3] = RNG.normal(size=3)
        mats.append(m)
    return M.tf_message(TS, t, [(p, c, m) for (p, c), m in zip(frames, mats, strict=True)], ros1=False)


def _joints(names: list[str], t: float) -> Any:
    msg = M.joint_state(TS, t, names, RNG.normal(size=len(names)), ros1=False)
    msg.position = RNG.normal(size=len(names))
    return msg


def _cases() -> list[tuple[str, Any]]:
    cases: list[tuple[str, Any]] = []
    for n in range(10):  # every residue of the string lengths modulo 8
        frame = "f" * n
        cases += [(FIX, _fix(frame, 1e9 + n * 0.123456789)), (TF, _tf([(frame, "c" * (9 - n)), ("map", frame)], -5.5)),
                  (JOINTS, _joints(["j" * k for k in range(n)], 12.25))]
    cases += [(TF, _tf([], 0.0)), (JOINTS, _joints([], 0.0)), (FIX, _fix("gnss_ü", 3.0))]
    return cases


@pytest.mark.parametrize(("msgtype", "msg"), _cases())
def test_the_same_values_as_rosbags(msgtype: str, msg: Any) -> None:
    raw = bytes(TS.serialize_cdr(msg, msgtype))
    ours = small_msgs.decode(raw, msgtype)
    assert ours is not None
    _same(ours, TS.deserialize_cdr(raw, msgtype))
    padded = raw + b"\x00" * (-len(raw) % 4)  # a writer's padding to 4 bytes: still read
    _same(small_msgs.decode(padded, msgtype), TS.deserialize_cdr(padded, msgtype))


def _broken(raw: bytes) -> list[bytes]:
    """Variants of a NavSatFix (frame_id "gnss") rosbags refuses or reads differently."""
    frame_len_at = 12
    no_nul = bytearray(raw)
    no_nul[frame_len_at + 4 + 4] = ord("x")  # the NUL closing "gnss"
    bad_utf8 = bytearray(raw)
    bad_utf8[frame_len_at + 4] = 0xFF
    return [raw[:-1], raw[:20], raw + b"\x00" * 4, bytes(no_nul), bytes(bad_utf8), b"\x00\x01\x00"]


def test_what_is_not_one_whole_message_is_left_to_rosbags() -> None:
    from rosbags.serde import SerdeError

    raw = bytes(TS.serialize_cdr(_fix("gnss", 1.0), FIX))
    for bad in _broken(raw):
        assert small_msgs.decode(bad, FIX) is None
        with pytest.raises((SerdeError, ValueError)):
            TS.deserialize_cdr(bad, FIX)  # the negative control: these are broken for rosbags too
    big = bytes(TS.serialize_cdr(_fix("gnss", 1.0), FIX, little_endian=False))
    assert small_msgs.decode(big, FIX) is None  # big endian: rosbags reads it
    assert small_msgs.decode(raw, "sensor_msgs/msg/Imu") is None  # not a type read here


def test_only_the_standard_definitions_are_read_here() -> None:
    defs = TS.fielddefs
    assert all(small_msgs.standard(defs, t) for t in (FIX, TF, JOINTS))
    assert not small_msgs.standard(defs, "sensor_msgs/msg/Imu")
    changed = copy.deepcopy(dict(defs))
    consts, fields = changed["sensor_msgs/msg/NavSatStatus"]
    changed["sensor_msgs/msg/NavSatStatus"] = (consts, [fields[0], (fields[1][0], fields[0][1])])  # service: int8
    assert not small_msgs.standard(changed, FIX)  # a type it holds differs
    del changed["geometry_msgs/msg/Quaternion"]
    assert not small_msgs.standard(changed, TF)  # a type it holds is missing
