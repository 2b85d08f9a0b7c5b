"""`mrnc-eval info` on the real Ouster OS1-128 recording (shared/data)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mrnc_eval.cli import main


def test_info_real_recording(real_ouster_mcap: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", str(real_ouster_mcap.parent), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)["results"][0]
    counts = {t["topic"]: (t["msgtype"], t["count"]) for t in info["topics"]}
    assert counts["/ouster/points"] == ("sensor_msgs/msg/PointCloud2", 3)
    assert counts["/ouster/imu"] == ("sensor_msgs/msg/Imu", 30)
    assert info["roles"]["lidar"] == "/ouster/points"
    assert info["roles"]["imu"] == "/ouster/imu"
    assert info["lidar"]["height"] == 128
    assert info["lidar"]["width"] == 1024
    assert info["lidar"]["per_point_time"]
    assert 0.3 < info["stats"]["duration_s"] < 0.32


def test_real_sweeps_have_per_point_time(real_ouster_mcap: Path) -> None:
    from mrnc_eval.io import open_log

    with open_log(real_ouster_mcap) as log:
        sweeps = list(log.sweeps())
    assert len(sweeps) == 3
    for s in sweeps:
        assert 50_000 < len(s) < 128 * 1024  # no-return points removed
        assert s.point_time.min() >= 0.0
        assert s.point_time.max() < 0.1
        assert s.ring.max() == 127
