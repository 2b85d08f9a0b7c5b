"""`mrnc-eval info` findings on generated logs with known defects, and sweep-order health."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.cli import main
from mrnc_eval.data import ImuSeries
from mrnc_eval.io import open_log
from mrnc_eval.io.writers import LogWriter
from tests.io.test_io_roundtrip import H, W, _cloud, write_sample


def _info(path: Path, capsys: pytest.CaptureFixture[str]) -> dict:
    assert main(["info", str(path), "--json"]) == 0
    return json.loads(capsys.readouterr().out)["results"][0]


def _messages(info: dict, topic: str) -> list[tuple[str, str]]:
    return [(f["level"], f["message"]) for f in info["findings"] if f["topic"] == topic]


def test_info_reports_duplicates_fix_ratio_and_coverage(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_sample(tmp_path / "dup.bag", "bag", duplicate_imu=True)
    info = _info(tmp_path / "dup.bag", capsys)
    assert info["container"] == "ros1"
    topics = {t["topic"]: t for t in info["topics"]}
    assert topics["/ouster/imu"]["msgtype"] == "sensor_msgs/Imu"  # ROS 1 names in a ROS 1 bag
    assert topics["/ouster/imu"]["count"] == 52
    assert topics["/ouster/imu"]["duplicates"] == 2
    assert topics["/ouster/imu"]["rate_hz"] == pytest.approx(51 / 0.49, abs=1e-3)
    assert topics["/ouster/points"]["max_gap_s"] == pytest.approx(0.1)
    assert ("warning", "2 duplicate header stamps (dropped when read)") in _messages(info, "/ouster/imu")
    assert ("warning", "GNSS fix ratio 75.0% (1 without fix)") in _messages(info, "/gnss/fix")
    lidar = _messages(info, "/ouster/points")
    assert ("ok", "per-point time present") in lidar
    assert ("ok", "IMU covers 3 of 3 sweeps (sweep duration 94 ms)") in lidar
    assert info["lidar"]["height"] == H
    assert info["lidar"]["width"] == W
    assert info["roles"]["commands"] == "/pump_cmd"
    assert info["roles"]["tf_static"] == "/tf_static"
    assert info["stats"]["duration_s"] == pytest.approx(0.49)


def test_info_flags_sweeps_the_imu_does_not_cover(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(2)
    t_imu = 100.15 + np.arange(30) * 0.01  # starts after the first two sweeps began
    with LogWriter(tmp_path / "late.mcap", "mcap") as w:
        w.write_imu("/ouster/imu", ImuSeries(t_imu, np.zeros((30, 3)), np.zeros((30, 3)), None, "os_imu"))
        for k in range(3):
            w.write_ouster_cloud("/ouster/points", 100.0 + 0.1 * k, *_cloud(rng))
    info = _info(tmp_path / "late.mcap", capsys)
    assert ("warning", "IMU covers 1 of 3 sweeps (sweep duration 94 ms)") in _messages(info, "/ouster/points")
    assert ("ok", "IMU rate 100.0 Hz, largest gap 10.0 ms") in _messages(info, "/ouster/imu")


def test_info_table_goes_to_stdout(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_sample(tmp_path / "a.mcap", "mcap")
    assert main(["info", str(tmp_path / "a.mcap")]) == 0
    out = capsys.readouterr().out
    for text in ("/ouster/points", "/gnss/fix", "ros2-mcap", "GNSS fix ratio 75.0%"):
        assert text in out


def test_duplicate_and_out_of_order_sweeps_are_skipped_and_noted(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    stamps = [1.0, 1.1, 1.1, 1.05, 1.2]  # arrival order: a duplicate, then a late cloud
    from mrnc_eval.io import messages as M

    w = LogWriter(tmp_path / "s.bag", "bag")
    conn = w._conn("/ouster/points", "sensor_msgs/msg/PointCloud2")
    for k, t in enumerate(stamps):  # recorded on arrival: record times increase, header stamps do not
        msg = M.ouster_cloud(w.ts, t, "os_sensor", *_cloud(rng), ros1=True, seq=k)
        w._writer.write(conn, int((1.0 + 0.1 * k) * 1e9), w._serialize(msg, "sensor_msgs/msg/PointCloud2"))
    w.close()
    with open_log(tmp_path / "s.bag") as log:
        got = [s.stamp for s in log.sweeps()]
        health = log.health("/ouster/points")
    assert got == pytest.approx([1.0, 1.1, 1.2])
    assert health.count == 5
    assert health.duplicates == 1
    assert health.out_of_order == 1
    assert health.notes == ("2 sweep(s) skipped: header stamp not after the previous sweep",)


def test_info_names_types_the_ros2_way_in_ros2_logs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_sample(tmp_path / "run.mcap", "mcap")
    topics = {t["topic"]: t for t in _info(tmp_path / "run.mcap", capsys)["topics"]}
    assert topics["/ouster/imu"]["msgtype"] == "sensor_msgs/msg/Imu"
