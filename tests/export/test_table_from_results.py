"""Issue 19 item 3: `table results/` builds Table I straight from slam result folders, with the
trajectory slam.table_trajectory names and the ground truth each run found; cross-checked against
the run's own APE and against `ape` on the same files."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.cli import main
from mrnc_eval.data import Trajectory
from mrnc_eval.io.trajectory_files import read_trajectory, write_tum
from mrnc_eval.results import read_result
from tests.export.conftest import Runs


def _json(args: list[str], capsys: pytest.CaptureFixture[str]) -> dict:
    capsys.readouterr()
    code = main(args)
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return json.loads(captured.out)


def _shifted(truth: Trajectory, amplitude_m: float) -> Trajectory:
    """The truth with a smooth error of `amplitude_m` that no rigid alignment removes."""
    wobble = amplitude_m * np.sin(np.linspace(0.0, 6.0 * np.pi, len(truth)))
    return Trajectory(truth.stamps, truth.positions + wobble[:, None] * [1.0, -1.0, 0.5], truth.quat_xyzw)


def _rewrite(run: Path, **extra: object) -> None:
    body = json.loads((run / "result.json").read_text())
    body["extra"].update(extra)
    body["extra"] = {k: v for k, v in body["extra"].items() if v != "<drop>"}
    (run / "result.json").write_text(json.dumps(body))


@pytest.fixture
def results_root(sim_runs: Runs, tmp_path: Path) -> Path:
    """A results folder as users have it: the lio run and its `latest` link, an older lio run of
    the same log with a wrong trajectory, a control run, and a second method whose online and
    smoothed trajectories differ (written before the reference was recorded in result.json)."""
    root = tmp_path / "results"
    shutil.copytree(sim_runs.slam, root / "yard-slam-lio")
    (root / "latest").symlink_to("yard-slam-lio")
    shutil.copytree(sim_runs.control, root / "yard-control")
    old = shutil.copytree(sim_runs.slam, root / "yard-slam-lio-old")
    truth = read_trajectory(f"{sim_runs.log}:/ground_truth")
    write_tum(old / "trajectory_online.tum", _shifted(truth, 3.0))
    _rewrite(old, method="lio")
    body = json.loads((old / "result.json").read_text())
    body["created_utc"] = "2000-01-01T00:00:00Z"
    (old / "result.json").write_text(json.dumps(body))
    other = shutil.copytree(sim_runs.slam, root / "nested" / "yard-slam-kiss")
    write_tum(other / "trajectory_online.tum", _shifted(truth, 0.05))
    write_tum(other / "trajectory.tum", _shifted(truth, 0.2))
    _rewrite(other, method="kiss-icp", ground_truth="<drop>")
    return root


def test_table_reads_slam_result_folders(sim_runs: Runs, results_root: Path, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    run = read_result(sim_runs.slam)
    monkeypatch.chdir(tmp_path)  # the references are found from anywhere
    kiss = results_root / "nested" / "yard-slam-kiss"
    for setting, lio_metric, kiss_file in (([], "ape_online_rmse_m", "trajectory_online.tum"),  # the default
                                           (["--set", "slam.table_trajectory=smoothed"], "ape_rmse_m",
                                            "trajectory.tum")):
        doc = _json(["table", str(results_root), "--json", "--max-diff", "0.02", *setting], capsys)  # slam's max_diff
        table = doc["meta"]["table"]
        assert table["row_labels"] == [run.log_id, "Mean"]
        assert table["column_labels"] == ["kiss-icp", "lio"]
        kiss_cell, lio_cell = table["cells"][0]
        assert [r["stats"]["value"] for r in doc["results"][:2]] == [kiss_cell, lio_cell]  # one item per cell
        own = run.metric(lio_metric)
        assert own is not None
        assert lio_cell == pytest.approx(own.value, rel=1e-6), setting  # the run's own APE
        ape = _json(["ape", f"{sim_runs.log}:/ground_truth", str(kiss / kiss_file), "--max-diff", "0.02", "--json",
                     "-a"],
                    capsys)
        assert kiss_cell == pytest.approx(ape["results"][0]["stats"]["rmse"], rel=1e-9), setting
    assert not any("yard-slam-lio-old" in n for n in table["notes"])
    recorded = run.extra["ground_truth"]  # as the run found it, with an absolute path
    assert recorded == f"{sim_runs.log.resolve()}:/ground_truth"


def test_table_from_results_honours_config_and_writes_files(results_root: Path, tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    doc = _json(["table", str(results_root), "--json", "--set", "evaluation.failed_min_matches=100000"], capsys)
    assert doc["meta"]["table"]["cells"][0] == ["Failed", "Failed"]
    assert doc["results"][0]["stats"]["value"] is None
    assert doc["results"][0]["failed"] == "Failed"
    cfg = tmp_path / "strict.yaml"
    cfg.write_text("evaluation:\n  failed_min_matches: 100000\n", encoding="utf-8")
    assert _json(["table", str(results_root), "--json", "--config", str(cfg)], capsys)["meta"]["table"]["cells"][0] == \
        ["Failed", "Failed"]
    assert main(["table", str(results_root), "--min-span-fraction", "2"]) == 2  # a config key's range
    assert main(["table", str(results_root), "--dump-config"]) == 0
    assert "table_trajectory: online" in capsys.readouterr().out
    assert main(["table", str(results_root), "--out", str(tmp_path / "t1.csv")]) == 0
    assert "kiss-icp" in (tmp_path / "t1.csv").read_text()
