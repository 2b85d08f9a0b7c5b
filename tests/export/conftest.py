"""One short simulated log (ROS 2 MCAP, 6 s, OS0-32 x 512, yard circle) with its SLAM and
control-replay result directories, shared by the export, API, compare and table tests."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.reports.conftest import tiny_cfg


@dataclass(frozen=True)
class Runs:
    log: Path
    slam: Path
    control: Path

    @property
    def root(self) -> Path:
        return self.slam.parent


@pytest.fixture(scope="session")
def sim_runs(tmp_path_factory) -> Runs:
    from mrnc_eval.commands import control, slam
    from mrnc_eval.recording.recorder import SimRequest, simulate_log

    root = tmp_path_factory.mktemp("export")
    cfg = tiny_cfg()
    log = root / "yard.mcap"
    simulate_log(log, cfg, SimRequest(scene="yard", path="circle", duration_s=6.0, lidar="os0-32", columns=512,
                                      seed=1))
    runs = Runs(log, root / "run" / "slam", root / "run" / "control")
    slam.run_log(log, cfg, runs.slam)
    control.run_log(log, cfg, runs.control, mode="replay")
    return runs
