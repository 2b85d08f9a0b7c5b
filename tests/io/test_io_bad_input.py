"""Bad input gets a one-line InputError naming file/topic/problem and exit code 4."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.cli import main
from mrnc_eval.errors import InputError
from mrnc_eval.io import open_log
from tests.io.test_io_roundtrip import write_sample


def _read_everything(path: Path) -> None:
    with open_log(path) as log:
        log.topics  # noqa: B018
        for role, reader in (("imu", log.imu), ("gnss", log.gnss), ("ground_truth", log.ground_truth)):
            if role in log.roles:
                reader()
        if "lidar" in log.roles:
            for _ in log.sweeps():
                pass


@pytest.mark.parametrize(("text", "problem"), [
    ("", "unrecognised log format"),
])
def test_unknown_file(tmp_path: Path, text: str, problem: str) -> None:
    p = tmp_path / "notes.txt"
    p.write_text(text)
    with pytest.raises(InputError, match=problem):
        open_log(p)


def test_missing_file_cli_exit_4(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", str(tmp_path / "missing.bag")]) == 4
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "missing.bag" in err[0]
    assert "no such file" in err[0]


def test_absent_topic_names_topic(tmp_path: Path) -> None:
    write_sample(tmp_path / "a.mcap", "mcap")
    with open_log(tmp_path / "a.mcap") as log, pytest.raises(InputError, match=r"\[/nope\]"):
        log.imu("/nope")


def test_empty_bag(tmp_path: Path) -> None:
    from mrnc_eval.io.writers import LogWriter

    LogWriter(tmp_path / "empty.bag", "bag").close()
    with pytest.raises(InputError, match="no topics"):
        open_log(tmp_path / "empty.bag")


def test_cloud_without_xyz(tmp_path: Path) -> None:
    from mrnc_eval.io import messages as M
    from mrnc_eval.io.writers import LogWriter

    w = LogWriter(tmp_path / "noxyz.mcap", "mcap")
    msg = M.ouster_cloud(w.ts, 1.0, "os", np.zeros((2, 2, 3)), *(np.zeros((2, 2)),) * 5, ros1=False)
    msg.fields = [f for f in msg.fields if f.name != "z"]
    conn = w._conn("/points", "sensor_msgs/msg/PointCloud2")
    w._writer.write(conn, 1_000_000_000, w._serialize(msg, "sensor_msgs/msg/PointCloud2"))
    w.close()
    with open_log(tmp_path / "noxyz.mcap") as log, pytest.raises(InputError, match=r"\[/points\].*no z field"):
        list(log.sweeps())


@pytest.mark.parametrize(("fmt", "name"), [("mcap", "f.mcap"), ("db3", "f.db3"), ("bag", "f.bag")])
def test_fuzz_truncated_and_flipped(tmp_path: Path, fmt: str, name: str,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    """Every damaged copy either reads cleanly or raises InputError naming the file (nothing
    else escapes), and `mrnc-eval info` on it exits 0 or 4 with a single stderr line."""
    src = tmp_path / name
    write_sample(src, fmt)
    data = src.read_bytes()
    rng = np.random.default_rng(7)
    outcomes = {"clean": 0, "error": 0}
    for k in range(50):
        damaged = bytearray(data)
        if k % 2 == 0:
            damaged = damaged[: int(rng.integers(0, len(data)))]
        else:
            for pos in rng.integers(0, len(data), size=int(rng.integers(1, 16))):
                damaged[pos] ^= 1 << int(rng.integers(0, 8))
        case = tmp_path / f"case{k}" / name
        case.parent.mkdir()
        case.write_bytes(bytes(damaged))
        try:
            _read_everything(case)
            outcomes["clean"] += 1
        except InputError as err:
            assert str(case) in str(err)  # noqa: PT017 - counting outcomes over many cases, not one raise
            assert "\n" not in str(err)  # noqa: PT017
            outcomes["error"] += 1
        capsys.readouterr()
        rc = main(["info", str(case), "--json"])
        err_lines = capsys.readouterr().err.strip().splitlines()
        assert rc in (0, 4), (k, rc, err_lines)
        if rc == 4:  # one error line (a role warning read before it, e.g. a truth topic kept out, may precede it)
            errors = [line for line in err_lines if not line.startswith("WARNING ")]
            assert len(errors) == 1, err_lines
            assert str(case) in errors[0], err_lines
        shutil.rmtree(case.parent)
    assert outcomes["error"] >= 20  # truncation is detected, not read as a shorter log


def test_plain_mcap_with_unsupported_encoding(tmp_path: Path) -> None:
    from mcap.writer import Writer

    p = tmp_path / "json.mcap"
    with p.open("wb") as fh:
        w = Writer(fh)
        w.start(profile="", library="test")
        sid = w.register_schema(name="Pose", encoding="jsonschema", data=b"{}")
        cid = w.register_channel(topic="/pose_json", message_encoding="json", schema_id=sid)
        w.add_message(channel_id=cid, log_time=1, publish_time=1, data=b"{}")
        w.finish()
    with open_log(p) as log:
        assert log.container == "mcap"
        (info,) = log.topics
        assert info.topic == "/pose_json"
        assert info.count == 1
        assert "'json'" in info.problem
        with pytest.raises(InputError, match=r"\[/pose_json\].*'json'.*not supported"):
            log.strings("/pose_json")


@pytest.mark.parametrize(("name", "data", "problem"), [
    ("e.mcap", b"", "not a readable MCAP file"),
    ("g.mcap", b"\x89MCAP0\r\n" + b"\x00" * 40, "not a readable MCAP file"),
    ("e.bag", b"", "cannot open ros1 log"),
    ("g.bag", b"#ROSBAG V2.0\n" + b"\xff" * 100, "cannot open ros1 log"),
    ("e.db3", b"", "cannot open ros2-sqlite3 log"),
    ("g.db3", b"SQLite format 3\x00" + b"\x01" * 200, "cannot open ros2-sqlite3 log"),
])
def test_empty_and_garbage_files(tmp_path: Path, name: str, data: bytes, problem: str,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / name
    p.write_bytes(data)
    with pytest.raises(InputError, match=problem):
        open_log(p)
    assert main(["info", str(p)]) == 4
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert str(p) in err[0]
    assert problem in err[0]


@pytest.mark.parametrize("text", ["", "::::", "- a\n- b", "rosbag2_bagfile_information: 3"])
def test_broken_bag_directory_metadata(tmp_path: Path, text: str) -> None:
    write_sample(tmp_path / "d", "mcap")
    (tmp_path / "d" / "metadata.yaml").write_text(text)
    with pytest.raises(InputError, match=str(tmp_path / "d")):
        _read_everything(tmp_path / "d")
