"""Issue 19 item 6: `simulate` takes the log format from OUT's suffix (and refuses a mismatch or an
unknown suffix), adds the suffix when there is none, dumps its configuration without OUT; readers
recognise a container by its first bytes, the suffix only as a fallback."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.cli import main
from mrnc_eval.data import ImuSeries
from mrnc_eval.errors import InputError, UsageError
from mrnc_eval.io import open_log
from mrnc_eval.io.containers import sniff
from mrnc_eval.io.trajectory_files import read_trajectory
from mrnc_eval.io.writers import LogWriter

SHORT = ["--duration", "1", "--lidar", "os0-32", "--columns", "512", "--scene", "field", "--path", "line"]


def _imu_log(path: Path, fmt: str, n: int = 40) -> Path:
    t = 5.0 + np.arange(n) / 100.0
    with LogWriter(path, fmt) as w:  # type: ignore[arg-type]
        w.write_imu("/imu", ImuSeries(t, np.tile([0.0, 0.0, 9.81], (n, 1)), np.zeros((n, 3)), frame_id="imu"))
    return path


def _opens_as(path: Path) -> str:
    with open_log(path) as lg:
        assert lg.topic_types(), path
        return lg.container


@pytest.mark.parametrize(("out", "fmt", "written", "container"), [
    ("sim/x.bag", None, "sim/x.bag", "ros1"),          # was a ROS 2 folder named x.bag
    ("out/run", "bag", "out/run.bag", "ros1"),         # was a ROS 1 bag without a suffix
    ("out/run", None, "out/run.mcap", "ros2-mcap"),    # was a ROS 2 bag folder named run
    ("x.db3", None, "x.db3", "ros2-sqlite3"),
    ("bagdir/", None, "bagdir", "ros2-sqlite3"),       # a folder: a ROS 2 bag folder
])
def test_simulate_takes_the_format_from_the_name(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                 out: str, fmt: str | None, written: str, container: str) -> None:
    args = ["simulate", f"{tmp_path}/{out}", *SHORT, *(["--format", fmt] if fmt else [])]
    assert main(args) == 0, capsys.readouterr().err
    log = tmp_path / written
    said = capsys.readouterr().err
    assert f"wrote {log} (" in said
    assert re.search(r" MB|kB", said)  # the size
    assert re.search(r", \d+\.\d s: ", said)  # the duration
    assert f"its ground truth {log.parent / log.name.split('.')[0]}.gt.tum" in said
    assert _opens_as(log) == container
    assert (log / "metadata.yaml").is_file() == log.is_dir()
    assert main(["info", str(log)]) == 0


@pytest.mark.parametrize(("out", "fmt", "says"), [
    ("y.txt", None, "unknown log suffix '.txt'"),
    ("x.bag", "mcap", "drop --format or name it"),
    ("x.mcap", "db3", "ROS 2 sqlite3"),
    ("x.db3", "bag", "ROS 1 bag"),
    ("folder/", "bag", "a ROS 1 bag is one file"),
])
def test_simulate_refuses_a_name_that_does_not_fit(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                   out: str, fmt: str | None, says: str) -> None:
    args = ["simulate", f"{tmp_path}/{out}", *SHORT, *(["--format", fmt] if fmt else [])]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert says in err
    assert len(err.strip().splitlines()) == 1
    assert not list(tmp_path.iterdir())  # nothing written


def test_simulate_dump_config_needs_no_out(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--dump-config"]) == 0
    assert "sim:" in capsys.readouterr().out
    assert main(["simulate"]) == 2
    assert "simulate needs OUT" in capsys.readouterr().err


def test_the_writer_refuses_a_suffix_of_another_format(tmp_path: Path) -> None:
    with pytest.raises(UsageError, match="ROS 1 bag"):
        LogWriter(tmp_path / "x.bag", "mcap")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(("fmt", "suffix", "container", "magic"), [
    ("bag", ".bag", "ros1", "ros1"), ("mcap", ".mcap", "ros2-mcap", "mcap"), ("db3", ".db3", "ros2-sqlite3",
                                                                                "ros2-sqlite3")])
def test_readers_recognise_a_container_by_its_first_bytes(tmp_path: Path, fmt: str, suffix: str, container: str,
                                                          magic: str) -> None:
    log = _imu_log(tmp_path / f"log{suffix}", fmt)
    assert sniff(log) == magic
    for name in ("renamed", "renamed.dat", *(s for s in (".bag", ".mcap", ".db3") if s != suffix)):
        other = tmp_path / (f"wrong{name}" if name.startswith(".") else name)
        shutil.copyfile(log, other)
        with open_log(other) as lg:  # neither a missing nor a wrong suffix misleads the reader
            assert lg.container == container, other.name
            assert lg.imu("/imu").stamps.size == 40
    assert not [p for p in tmp_path.iterdir() if p.is_symlink()]  # the links rosbags needed are gone
    with pytest.raises(InputError, match="is a log"):
        read_trajectory(tmp_path / "renamed")  # a log without a suffix is still named a log


def test_the_suffix_is_the_fallback(tmp_path: Path) -> None:
    junk = tmp_path / "broken.bag"
    junk.write_bytes(b"not a bag at all")
    with pytest.raises(InputError, match="ros1"):
        open_log(junk)
    unknown = tmp_path / "notes"
    unknown.write_bytes(b"hello")
    with pytest.raises(InputError, match="unrecognised log format"):
        open_log(unknown)


@pytest.mark.parametrize("fmt", ["db3", "mcap"])
def test_a_ros2_bag_folder_named_dot_bag_opens(tmp_path: Path, fmt: str) -> None:
    """What `simulate x.bag` wrote before: a ROS 2 bag folder whose name says ROS 1."""
    folder = _imu_log(tmp_path / "x", fmt).rename(tmp_path / "x.bag")
    with open_log(folder) as lg:
        assert lg.container == f"ros2-{'sqlite3' if fmt == 'db3' else 'mcap'}"
        assert lg.imu("/imu").stamps.size == 40
