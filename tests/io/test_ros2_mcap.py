"""A single ROS 2 MCAP file opened from its summary (io/ros2_mcap.py) against rosbags' AnyReader
(io/sources.RosbagsSource): the same channels, the same messages decoded to equal objects, the
same full read; a file that is not plainly well-formed still opened by AnyReader; what a run reads
of one imports no part of rosbags (a ROS 1 bag does: the negative control)."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import textwrap
from contextlib import closing
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mrnc_eval.errors import InputError
from mrnc_eval.io.log_source import LogSource
from mrnc_eval.io.ros2_mcap import NotPlain, Ros2McapSource, read_summary
from mrnc_eval.io.sources import RosbagsSource
from mrnc_eval.io.typestore import typestore_for
from tests.io.test_io_roundtrip import write_sample

REPO = Path(__file__).resolve().parents[2]
CIRCLE = REPO / "sample_logs" / "circle_soft_ground.mcap"
BAG = REPO / "sample_logs" / "loop_forest.bag"


def _same(ours: Any, theirs: Any, where: str = "msg") -> None:
    """Deep equality of a decoded message with rosbags' (ours may be rosbags' own or an object
    alike, io/small_msgs.py): the same fields, arrays (dtype and values) and values of the same type."""
    if isinstance(theirs, np.ndarray):
        assert isinstance(ours, np.ndarray), where
        assert ours.dtype == theirs.dtype, where
        np.testing.assert_array_equal(ours, theirs, err_msg=where)
    elif dataclasses.is_dataclass(theirs):
        for f in dataclasses.fields(theirs):
            if not (f.name.startswith("__") or f.name.isupper()):  # rosbags' class tag and constants: unread
                _same(getattr(ours, f.name), getattr(theirs, f.name), f"{where}.{f.name}")
    elif isinstance(theirs, (list, tuple)):
        assert len(ours) == len(theirs), where
        for k, (x, y) in enumerate(zip(ours, theirs, strict=True)):
            _same(x, y, f"{where}[{k}]")
    else:
        assert type(ours) is type(theirs), where
        assert ours == theirs or (ours != ours and theirs != theirs), where


SMALL = ("sensor_msgs/msg/NavSatFix", "tf2_msgs/msg/TFMessage", "sensor_msgs/msg/JointState")  # io/small_msgs.py


def _compare(path: Path) -> tuple[int, set[str]]:
    """Channels and every message of every topic equal both ways; the messages compared."""
    fast = Ros2McapSource(path, read_summary(path))
    full = RosbagsSource([path], ros1=False)
    try:
        assert fast.channels == full.channels
        n = 0
        for topic in fast.channels:
            ours = list(fast.messages([topic]))
            theirs = list(full.messages([topic]))
            assert [(t, r, bytes(m)) for t, r, m in ours] == [(t, r, bytes(m)) for t, r, m in theirs]
            for _t, _rec, raw in theirs[:400]:
                _same(fast.deserialize(raw, topic), full.deserialize(raw, topic), topic)
                n += 1
        read_here = {t for t, ch in fast.channels.items() if ch.msgtype in SMALL}
        return n, read_here
    finally:
        fast.close()
        full.close()


def test_the_sample_log_reads_as_through_anyreader() -> None:
    n, read_here = _compare(CIRCLE)
    assert n > 1000
    assert len(read_here) >= 2  # NavSatFix, TFMessage or JointState topics among them


def test_the_real_recording_reads_as_through_anyreader(real_ouster_mcap: Path) -> None:
    assert _compare(real_ouster_mcap)[0] > 10


def test_a_written_log_reads_as_through_anyreader(tmp_path: Path) -> None:
    write_sample(tmp_path / "log.mcap", "mcap")
    assert _compare(tmp_path / "log.mcap")[0] > 50
    with closing(LogSource([tmp_path / "log.mcap"])) as src:
        assert isinstance(src.src, Ros2McapSource)
        topic = next(t for t, ch in src.channels.items() if ch.msgtype == "sensor_msgs/msg/Imu")
        with pytest.raises(InputError, match="cannot decode"):  # a broken message: AnyReader's error, as before
            src.decode(b"\x00\x01\x00\x00\x01", topic)


def _mcap_without_profile(path: Path) -> None:
    """A ROS 2 MCAP file (CDR, ros2msg schemas) whose header names no profile."""
    from mcap.writer import Writer

    from mrnc_eval.io import messages as M

    ts = typestore_for(ros1=False)
    msgdef, _ = ts.generate_msgdef("sensor_msgs/msg/Imu", ros_version=2)
    with path.open("wb") as fh:
        w = Writer(fh)
        w.start(profile="", library="test")
        sid = w.register_schema(name="sensor_msgs/msg/Imu", encoding="ros2msg", data=msgdef.encode())
        cid = w.register_channel(topic="/imu", message_encoding="cdr", schema_id=sid)
        for k in range(20):
            msg = M.imu(ts, 3.0 + 0.01 * k, "imu", (k, 0, 9.81), (0, 0, 0.1), None, ros1=False)
            w.add_message(channel_id=cid, log_time=3_000_000_000 + 10_000_000 * k, publish_time=0,
                          data=bytes(ts.serialize_cdr(msg, "sensor_msgs/msg/Imu")))
        w.finish()


def test_a_file_not_plainly_ros2_is_opened_by_anyreader(tmp_path: Path) -> None:
    path = tmp_path / "noprofile.mcap"
    _mcap_without_profile(path)
    with pytest.raises(NotPlain, match="profile"):
        read_summary(path)
    with pytest.raises(InputError, match="Profile is not ros2"):  # AnyReader opened it: its refusal, as before
        LogSource([path])


SCRIPT = textwrap.dedent("""
    import sys
    from mrnc_eval.io import open_log
    with open_log(sys.argv[1]) as lg:  # what `slam` reads before its sweeps: the overview pass first
        lg.duration_s
        lg.imu()
        lg.static_transforms()
        lg.gnss()
    print("rosbags" in sys.modules)
""")


@pytest.mark.parametrize(("log", "imported"), [(CIRCLE, False), (BAG, True)])
def test_rosbags_imported_only_for_bags(log: Path, imported: bool) -> None:
    """What a slam run reads of a plain ROS 2 MCAP file needs no part of rosbags (io/ros2_mcap.py)."""
    proc = subprocess.run([sys.executable, "-c", SCRIPT, str(log)], capture_output=True, text=True, check=True,
                          env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"}, timeout=300)
    assert proc.stdout.strip().splitlines()[-1] == str(imported)


def test_bag_readers_errors_are_data_errors_once_imported() -> None:
    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Ros1ReaderError
    from rosbags.rosbag2 import ReaderError as Ros2ReaderError

    from mrnc_eval.io.library_errors import data_errors

    assert {AnyReaderError, Ros1ReaderError, Ros2ReaderError} <= set(data_errors())


def test_a_summary_anyreader_refuses_is_refused_as_before(tmp_path: Path) -> None:
    """A summary start inside the header: AnyReader's error, not a fast path that reads it anyway."""
    data = bytearray(CIRCLE.read_bytes())
    at = len(data) - 8 - 20  # the footer's summary start
    data[at:at + 8] = (8).to_bytes(8, "little")
    path = tmp_path / "early.mcap"
    path.write_bytes(bytes(data))
    with pytest.raises(NotPlain):
        read_summary(path)
    with pytest.raises(InputError, match="Invalid MCAP summary offset"):
        LogSource([path])


def test_a_map_whose_entries_overrun_its_length_is_refused_as_before(tmp_path: Path) -> None:
    """The first chunk index's message index offsets (10-byte entries) given 5 bytes less than
    they hold: read on past it, the fast path opened a file AnyReader refuses."""
    from mrnc_eval.io import mcap_summary

    data = bytearray(CIRCLE.read_bytes())
    summary_start = int.from_bytes(data[-28:-20], "little")
    at = summary_start
    while data[at] != 0x08:  # the summary's records up to its first ChunkIndex
        at += 9 + int.from_bytes(data[at + 1:at + 9], "little")
    offsets_len = at + 9 + 32  # opcode, length, 4 u64 before the map's byte length
    n = int.from_bytes(data[offsets_len:offsets_len + 4], "little")
    data[offsets_len:offsets_len + 4] = (n - 5).to_bytes(4, "little")
    path = tmp_path / "overrun.mcap"
    path.write_bytes(bytes(data))
    with pytest.raises(mcap_summary.Unreadable, match="map"):
        mcap_summary.read(path)
    with pytest.raises(InputError, match="multiple of 10 bytes"):  # AnyReader's refusal
        LogSource([path])
    assert mcap_summary.read(CIRCLE) is not None  # the negative control


def test_a_footer_of_another_length_is_refused_as_before(tmp_path: Path) -> None:
    data = bytearray(CIRCLE.read_bytes())
    data[-8 - 20 - 8] = 21  # the footer record's length (20)
    path = tmp_path / "footer.mcap"
    path.write_bytes(bytes(data))
    with pytest.raises(NotPlain):
        read_summary(path)
    with pytest.raises(InputError, match="Invalid MCAP footer"):  # AnyReader's refusal
        LogSource([path])
