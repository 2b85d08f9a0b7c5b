from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from mrnc_eval.config import Config
from mrnc_eval.sim.recorder import SimRequest, simulate_log


def tiny_cfg() -> Config:
    cfg = Config()
    return replace(cfg, sim=replace(cfg.sim, lidar=replace(cfg.sim.lidar, record_every=2)))


@pytest.fixture(scope="session")
def tiny_logs(tmp_path_factory) -> Path:
    """Three short logs (mcap, ROS 1, nested folder) for nightly tests."""
    root = tmp_path_factory.mktemp("logs")
    cfg = tiny_cfg()
    simulate_log(root / "a.mcap", cfg, SimRequest(scene="yard", path="circle", duration_s=8.0, lidar="os0-32",
                                                   columns=512, seed=1))
    simulate_log(root / "b.bag", cfg, SimRequest(scene="forest", path="line", duration_s=8.0, lidar="os0-32",
                                                  columns=512, seed=2, fmt="bag"))
    (root / "nested").mkdir()
    simulate_log(root / "nested" / "c.mcap", cfg, SimRequest(scene="yard", path="figure8", duration_s=8.0,
                                                              lidar="os0-32", columns=512, seed=3))
    return root
