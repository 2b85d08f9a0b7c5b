"""Slow: a 2.5-minute OS0-64 x 1024 10 Hz forest loop from the simulator. The LIO replay stays
below 10 cm APE after SE(3) alignment, loop closure does not leave more end-point drift than the
run without it, and kiss-icp on the same sweeps is less accurate.
Run: .venv/bin/python -m pytest -m slow tests/slam/test_slam_loop_accuracy.py -s
"""

from __future__ import annotations

from pathlib import Path

import pytest

from mrnc_eval.config import Config, replace_path

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def loop_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from mrnc_eval.sim.recorder import SimRequest, simulate_log

    cfg = replace_path(Config(), "sim.path_size_m", 16.0)  # 16 m loop: ~150 s at the mission speed
    return simulate_log(tmp_path_factory.mktemp("loop") / "loop_forest_150s.mcap", cfg,
                        SimRequest(scene="forest", path="loop", lidar="os0-64", columns=1024, seed=2))


def test_loop_log_lio_accurate_loop_helps_and_beats_kiss_icp(loop_log: Path, tmp_path: Path) -> None:
    from mrnc_eval.pipelines.slam import run_log

    lio = run_log(loop_log, Config(), tmp_path / "lio")
    no_loop = run_log(loop_log, replace_path(Config(), "slam.use_loop_closure", False), tmp_path / "noloop")
    kiss = run_log(loop_log, Config(), tmp_path / "kiss", method="kiss-icp")
    v = lambda r, n: r.metric(n).value  # noqa: E731
    print(f"\nAPE RMSE m: lio {v(lio, 'ape_rmse_m'):.4f} (end drift {v(lio, 'end_drift_m'):.4f}, "
          f"{v(lio, 'loop_closures')} loops) | no loop {v(no_loop, 'ape_rmse_m'):.4f} (end drift "
          f"{v(no_loop, 'end_drift_m'):.4f}) | kiss-icp {v(kiss, 'ape_rmse_m'):.4f}")
    assert v(lio, "ape_span_s") > 120.0
    assert v(lio, "ape_rmse_m") < 0.10
    assert v(lio, "loop_closures") >= 1 and v(no_loop, "loop_closures") == 0
    assert v(lio, "end_drift_m") <= v(no_loop, "end_drift_m") + 0.005
    assert v(lio, "ape_rmse_m") < v(kiss, "ape_rmse_m")
