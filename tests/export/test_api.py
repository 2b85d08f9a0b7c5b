"""mrnc_eval.api: the functions return what the CLI writes, and the README's example runs."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval import api
from mrnc_eval.results import read_result
from tests.export.conftest import Runs

README = Path(__file__).resolve().parents[2] / "README.md"


def readme_example() -> str:
    section = README.read_text(encoding="utf-8").split("## Viewing results", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_readme_example_runs(sim_runs: Runs, tmp_path: Path, monkeypatch, capsys) -> None:
    """The README's code block, executed as written in a folder where its sample log names point at
    the short simulated log (a stand-in: the committed samples take minutes of SLAM)."""
    from mrnc_eval.history import History, LogRecord

    code = readme_example()
    assert len([line for line in code.splitlines() if line.strip()]) <= 12
    (tmp_path / "sample_logs").mkdir()
    os.symlink(sim_runs.log, tmp_path / "sample_logs" / "circle_soft_ground.mcap")
    os.symlink(sim_runs.log.with_name("yard.gt.tum"), tmp_path / "sample_logs" / "circle_soft_ground.gt.tum")
    History(tmp_path / "nightly_reports" / "history.sqlite").record(LogRecord(
        "2026-11-20", "circle_soft_ground", "r", "circle_soft_ground.mcap", "0", "h", "ok", "", "t",
        (("slam/ape/ape_rmse_m", 0.01, "m"),)))
    monkeypatch.chdir(tmp_path)
    scope: dict = {}
    exec(compile(code, "README.md", "exec"), scope)
    slam, err, ctl, same, history = (scope[k] for k in ("slam", "err", "ctl", "same", "history"))
    assert same.metrics == slam.metrics  # load_result reads back what run_slam wrote
    ape_metric = slam.metric("ape_rmse_m")
    assert ape_metric is not None
    # the SLAM command's own APE; the TUM file rounds positions to 1 nm, hence not bit-equal
    assert err.stats["rmse"] == pytest.approx(ape_metric.value, rel=1e-6)
    assert len(err.to_dataframe()) == err.n
    assert set(ctl.to_dataframe()["group"]) >= {"control/recorded/left", "control/recorded/right"}
    assert list(history["metric"]) == ["slam/ape/ape_rmse_m"]
    assert "APE RMSE" in capsys.readouterr().out


def test_result_dataframes_hold_the_written_numbers(sim_runs: Runs) -> None:
    result = api.load_result(sim_runs.slam)
    frame = result.to_dataframe()
    assert len(frame) == len(result.metrics)
    row = frame.set_index("name").loc["ape_rmse_m"]
    assert row["value"] == result.metric("ape_rmse_m").value
    assert row["unit"] == "m"
    traj = api.read_trajectory(sim_runs.slam / "trajectory.tum")
    tf = traj.to_dataframe()
    np.testing.assert_array_equal(tf[["x", "y", "z"]].to_numpy(), traj.positions)
    np.testing.assert_array_equal(tf["t_s"].to_numpy(), traj.stamps)
    gt = sim_runs.log.with_name("yard.gt.tum")
    ape = api.ape(gt, traj, align="se3", max_diff=0.02)
    af = ape.to_dataframe()
    assert af["error_m"].pow(2).mean() ** 0.5 == pytest.approx(ape.stats["rmse"], rel=1e-9)
    rpe = api.rpe(gt, traj, delta=1.0, max_diff=0.02)
    assert len(rpe.to_dataframe()) == rpe.n
    with api.read_log(sim_runs.log) as lg:
        assert lg.has_role("ground_truth")


def test_api_and_cli_agree_and_errors_are_typed(sim_runs: Runs, tmp_path: Path) -> None:
    from mrnc_eval.errors import InputError, UsageError

    cli_result = read_result(sim_runs.control)
    api_result = api.run_control(sim_runs.log, tmp_path / "ctl", overrides=["sim.lidar.record_every=2"])
    assert api_result.to_dataframe()["value"].tolist() == pytest.approx(
        cli_result.to_dataframe()["value"].tolist(), nan_ok=True)
    with pytest.raises(InputError):
        api.load_result(tmp_path)
    with pytest.raises(UsageError):
        api.run_control(sim_runs.log, tmp_path / "x", cfg=api.config(), overrides=["control.raid.beta=1"])
    with pytest.raises(InputError):
        api.load_history(tmp_path)
