"""Short simulated logs shared by the SLAM tests (ideal sensor profile, OS0-32 x 512 at 10 Hz)."""

from __future__ import annotations

from pathlib import Path

import pytest

from mrnc_eval.config import Config, replace_path
from mrnc_eval.recording.recorder import SimRequest, simulate_log


def _line_log(tmp_path_factory: pytest.TempPathFactory, scene: str, record_every: int = 1) -> Path:
    d = tmp_path_factory.mktemp(scene)
    cfg = replace_path(Config(), "sim.lidar.record_every", record_every)
    return simulate_log(d / f"{scene}.mcap", cfg, SimRequest(scene=scene, path="line", duration_s=6.0,
                                                             lidar="os0-32", columns=512, seed=3))


@pytest.fixture(scope="session")
def corridor_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _line_log(tmp_path_factory, "corridor")


@pytest.fixture(scope="session")
def yard_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The same drive among buildings: the negative control of the corridor."""
    return _line_log(tmp_path_factory, "yard")




@pytest.fixture(scope="session")
def throttled_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The yard drive with every 10th sweep recorded: 1 Hz sweeps of a 10 Hz OS0."""
    return _line_log(tmp_path_factory, "yard", record_every=10)
