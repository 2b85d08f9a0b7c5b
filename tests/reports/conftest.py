from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.config import Config
from mrnc_eval.recording.recorder import SimRequest, simulate_log


def tiny_cfg() -> Config:
    cfg = Config()
    return replace(cfg, sim=replace(cfg.sim, lidar=replace(cfg.sim.lidar, record_every=2)))


@pytest.fixture(scope="session")
def tiny_logs(tmp_path_factory) -> Path:
    """Two short simulated logs (ROS 2 MCAP; ROS 1 bag in a nested folder) for the real pipelines."""
    root = tmp_path_factory.mktemp("logs")
    cfg = tiny_cfg()
    simulate_log(root / "a.mcap", cfg, SimRequest(scene="yard", path="circle", duration_s=6.0, lidar="os0-32",
                                                   columns=512, seed=1))
    (root / "nested").mkdir()
    simulate_log(root / "nested" / "b.bag", cfg, SimRequest(scene="forest", path="figure8", duration_s=6.0,
                                                             lidar="os0-32", columns=512, seed=2, fmt="bag"))
    return root


def write_imu_log(path: Path, n: int, fmt: str = "mcap", topic: str = "/imu") -> Path:
    """A small real log (IMU only) for the executor and history tests."""
    from mrnc_eval.data import ImuSeries
    from mrnc_eval.io.writers import LogWriter

    t = 1.0 + np.arange(n) / 100.0
    with LogWriter(path, fmt) as w:
        w.write_imu(topic, ImuSeries(t, np.tile([0.0, 0.0, 9.81], (n, 1)), np.zeros((n, 3)), frame_id="imu"))
    return path


@pytest.fixture(scope="session")
def imu_logs(tmp_path_factory) -> Path:
    """Five small logs in nested folders and three containers."""
    root = tmp_path_factory.mktemp("imu_logs")
    (root / "night" / "deeper").mkdir(parents=True)
    write_imu_log(root / "l1.mcap", 50)
    write_imu_log(root / "l2.bag", 80, "bag")
    write_imu_log(root / "night" / "l3.mcap", 120)
    write_imu_log(root / "night" / "deeper" / "l4.mcap", 30)
    write_imu_log(root / "night" / "l5", 60, "db3")
    (root / "l1.gt.tum").write_text("1.0 0 0 0 0 0 0 1\n", encoding="utf-8")  # beside-the-log ground truth: not a log
    return root
