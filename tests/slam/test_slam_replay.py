"""SLAM replay: accuracy against simulator ground truth, real Ouster bytes, degeneracy,
missing IMU / per-point time."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.config import Config, replace_path
from mrnc_eval.io import open_log
from mrnc_eval.results import read_result
from mrnc_eval.sim.recorder import SimRequest, simulate_log
from mrnc_eval.slam import se3
from mrnc_eval.slam.replay import run_slam

REPO = Path(__file__).resolve().parents[2]
CIRCLE = REPO / "sample_logs" / "circle_soft_ground.mcap"


def test_circle_sample_log_ape_below_10cm(tmp_path: Path) -> None:
    from mrnc_eval.commands.slam import run_log

    result = run_log(CIRCLE, Config(), tmp_path / "run")
    ape = result.metric("ape_rmse_m").value
    assert ape < 0.10
    assert result.metric("ape_span_s").value > 90.0  # the whole circle, not a piece of it
    back = read_result(tmp_path / "run")
    assert back.metric("ape_rmse_m").value == ape
    assert (tmp_path / "run" / "trajectory.tum").exists()
    assert (tmp_path / "run" / "map.ply").exists()
    assert back.metric("rtf").value > 0
    assert "matching" in back.extra["timing_ms"]


def test_real_ouster_sweeps_register(real_ouster_mcap: Path) -> None:
    cfg = replace_path(Config(), "slam.mapping_interval_s", 0.0)  # register all three 10 Hz sweeps
    with open_log(real_ouster_mcap) as lg:
        out = run_slam(lg.sweeps(), lg.imu(), cfg.slam, sensor_to_imu=lg.transform("os_sensor", "os_imu"))
    assert out.stamps.size == 3
    for a, b in zip(out.poses[:-1], out.poses[1:], strict=True):
        step = se3.inv(a) @ b
        assert np.all(np.isfinite(step))
        assert np.linalg.norm(step[:3, 3]) < 1.0  # 0.1 s apart
        assert np.degrees(se3.delta_angle(step)) < 5.0


def test_slam_verb_on_real_recording_says_there_is_no_ground_truth(real_ouster_mcap: Path, tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    from mrnc_eval.cli import main

    assert main(["slam", str(real_ouster_mcap), "--out", str(tmp_path), "--set", "slam.mapping_interval_s=0"]) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert "APE RMSE n/a (no ground truth)" in line
    assert "nan" not in line
    (run_dir,) = tmp_path.iterdir()
    assert len((run_dir / "trajectory.tum").read_text().splitlines()) == 3
    assert read_result(run_dir).metric("ape_rmse_m") is None


@pytest.fixture(scope="module")
def corridor_log(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("corridor")
    return simulate_log(d / "corridor.mcap", Config(), SimRequest(scene="corridor", path="line", duration_s=6.0,
                                                                   lidar="os0-32", columns=512, seed=3))


def test_degenerate_corridor_reports_degeneracy(corridor_log: Path) -> None:
    cfg = Config()
    with open_log(corridor_log) as lg:
        out = run_slam(lg.sweeps(), lg.imu(), cfg.slam, sensor_to_imu=lg.transform("os_sensor", "os_imu"))
    assert any(e.kind == "degeneracy" for e in out.events)


def test_without_imu_and_point_time_runs_with_warnings(corridor_log: Path) -> None:
    cfg = Config()
    with open_log(corridor_log) as lg:
        sweeps = [replace(s, point_time=None) for s in lg.sweeps()]
    out = run_slam(sweeps, None, cfg.slam, sensor_to_imu=np.eye(4))
    assert any("no IMU" in w for w in out.warnings)
    assert any("per-point time" in w for w in out.warnings)
    assert out.stamps.size > 10
    assert np.all(np.isfinite(out.poses))


def test_voxel_downsample_keeps_one_centroid_per_voxel() -> None:
    from mrnc_eval.slam.features import voxel_downsample

    pts = np.random.default_rng(0).uniform(-30, 30, (20000, 3))
    out = voxel_downsample(pts, 0.5)
    keys = np.floor(pts / 0.5).astype(np.int64)
    uniq, inv = np.unique(keys, axis=0, return_inverse=True)
    assert out.shape[0] == uniq.shape[0]
    ref = np.zeros((uniq.shape[0], 3))
    np.add.at(ref, inv.ravel(), pts)
    ref /= np.bincount(inv.ravel())[:, None]
    order_out = np.lexsort(np.floor(out / 0.5).astype(np.int64).T[::-1])
    order_ref = np.lexsort(uniq.T[::-1])
    np.testing.assert_allclose(out[order_out], ref[order_ref], atol=1e-9)
