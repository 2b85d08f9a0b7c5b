"""What `slam` prints per log: how many of the log's sweeps were mapped and at what interval,
and without ground truth how to give one and the GNSS comparison the run made."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.commands.slam import LogInputs, _add_run_metrics, _print_summary
from mrnc_eval.config import Config
from mrnc_eval.results import Metric, RunResult
from mrnc_eval.slam.output import STAGES, SlamOutput


def _inputs(n_sweeps: int) -> LogInputs:
    return LogInputs(duration_s=52.5, base_to_sensor=np.eye(4), imu=None, sensor_to_imu=np.eye(4), gnss=None,
                     ground_truth=None, antenna=np.zeros(3), antenna_in_sensor=np.zeros(3), n_sweeps=n_sweeps,
                     max_sweep_gap_s=0.3)


def _output(mapped: int, decoded: int) -> SlamOutput:
    poses = np.tile(np.eye(4), (mapped, 1, 1))
    return SlamOutput(stamps=np.arange(mapped) * 0.39, poses=poses, kf_stamps=np.zeros(0),
                      kf_poses=np.zeros((0, 4, 4)), map_points=np.zeros((0, 3)),
                      timing_ms={st: [1.0] * mapped for st in STAGES}, events=[], warnings=[], n_sweeps=decoded,
                      wall_s=19.4)


@pytest.mark.parametrize(("method", "every"), [("lio", "every 0.15 s or more (slam.mapping_interval_s)"),
                                               ("kiss-icp", "every sweep")])
def test_mapping_count_is_of_the_sweeps_in_the_log(method: str, every: str) -> None:
    r = RunResult(kind="slam", log_path="loop_forest.bag", log_id="loop_forest")
    # 236 sweeps in the log; the 0.15 s interval let 134 through and all 134 were mapped
    _add_run_metrics(r, _output(134, 134), _inputs(236), method, 31.0, 0.15)
    assert r.extra["mapping_rate"] == f"mapping 134 of 236 sweeps, {every}, 2.6 Hz"


def _printed(r: RunResult, capsys: pytest.CaptureFixture[str]) -> str:
    from mrnc_eval.evaluation.comparison import Cell

    _print_summary([(Path("results/run"), r)], {("loop_forest", "lio"): Cell(None, "no ground truth")},
                   ["loop_forest"], Config(), json_out=False)
    return capsys.readouterr().out


def _run(*extra: Metric) -> RunResult:
    base = [Metric(name="rtf", value=2.7, unit="", group="slam"),
            Metric(name="keyframes", value=26, unit="", group="slam"),
            Metric(name="loop_closures", value=12, unit="", group="slam")]
    r = RunResult(kind="slam", log_path="logs/loop_forest.bag", log_id="loop_forest", metrics=[*base, *extra])
    r.extra["mapping_rate"] = "mapping 134 of 236 sweeps, every 0.15 s or more (slam.mapping_interval_s), 2.6 Hz"
    return r


def test_without_ground_truth_says_how_to_give_one_and_the_gnss_comparison(capsys) -> None:
    line = _printed(_run(Metric(name="ape_gnss_rmse_m", value=1.82, unit="m", group="slam/ape")), capsys)
    assert "n/a (no ground truth: give one as loop_forest.gt.tum beside the log (TUM) or --set " \
           "io.roles.ground_truth=TOPIC)" in line
    assert "vs GNSS 1.820 m (2-D" in line
    assert "mapping 134 of 236 sweeps" in line


def test_with_ground_truth_no_hint(capsys) -> None:
    line = _printed(_run(Metric(name="ape_rmse_m", value=0.0288, unit="m", group="slam/ape"),
                         Metric(name="ape_gnss_rmse_m", value=1.82, unit="m", group="x")),
                    capsys)
    assert "smoothed 0.0288 m" in line
    assert "no ground truth" not in line
    assert "GNSS" not in line
