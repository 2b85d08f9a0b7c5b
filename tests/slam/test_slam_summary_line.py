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
    return LogInputs(52.5, np.eye(4), None, np.eye(4), None, None, np.zeros(3), np.zeros(3), n_sweeps, 0.3)


def _output(mapped: int, decoded: int) -> SlamOutput:
    poses = np.tile(np.eye(4), (mapped, 1, 1))
    return SlamOutput(np.arange(mapped) * 0.39, poses, np.zeros(0), np.zeros((0, 4, 4)), np.zeros((0, 3)),
                      {st: [1.0] * mapped for st in STAGES}, [], [], decoded, 19.4)


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
    base = [Metric("rtf", 2.7, "", "slam"), Metric("keyframes", 26, "", "slam"),
            Metric("loop_closures", 12, "", "slam")]
    r = RunResult(kind="slam", log_path="logs/loop_forest.bag", log_id="loop_forest", metrics=[*base, *extra])
    r.extra["mapping_rate"] = "mapping 134 of 236 sweeps, every 0.15 s or more (slam.mapping_interval_s), 2.6 Hz"
    return r


def test_without_ground_truth_says_how_to_give_one_and_the_gnss_comparison(capsys) -> None:
    line = _printed(_run(Metric("ape_gnss_rmse_m", 1.82, "m", "slam/ape")), capsys)
    assert "n/a (no ground truth: give one as loop_forest.gt.tum beside the log (TUM) or --set " \
           "io.roles.ground_truth=TOPIC)" in line
    assert "vs GNSS 1.820 m (2-D" in line
    assert "mapping 134 of 236 sweeps" in line


def test_with_ground_truth_no_hint(capsys) -> None:
    line = _printed(_run(Metric("ape_rmse_m", 0.0288, "m", "slam/ape"), Metric("ape_gnss_rmse_m", 1.82, "m", "x")),
                    capsys)
    assert "smoothed 0.0288 m" in line
    assert "no ground truth" not in line
    assert "GNSS" not in line
