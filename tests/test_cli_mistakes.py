"""Issue 19, mistakes that ended in tracebacks: a result folder or a bare log given to `ape`."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from mrnc_eval.cli import main

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
GT = SAMPLES / "loop_forest.gt.tum"
LOG = SAMPLES / "loop_forest.bag"


def test_a_result_folder_stands_for_its_trajectory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "results" / "run-1"
    run.mkdir(parents=True)
    shutil.copy(GT, run / "trajectory.tum")
    assert main(["ape", str(GT), str(run) + "/", "--json"]) == 0
    by_folder = json.loads(capsys.readouterr().out)
    assert main(["ape", str(GT), str(run / "trajectory.tum"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == by_folder


def test_another_folder_says_which_file_to_pass(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["ape", str(GT), str(tmp_path)]) == 4
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "is a folder, not a trajectory file" in err
    assert "trajectory.tum" in err


def test_a_log_without_topic_lists_its_pose_topics(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["ape", str(LOG), str(GT)]) == 4
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "is a log" in err
    assert f"{LOG}:/TOPIC" in err
    assert "/ground_truth" in err
    assert "/wheel_odom" in err


def test_a_folder_of_logs_points_to_nightly_or_a_glob(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    shutil.copy(LOG, logs / "a.bag")
    assert main(["slam", str(logs), "--out", str(tmp_path / "out")]) == 4
    err = capsys.readouterr().err
    assert "a folder of 1 log(s), not one log" in err
    assert f"mrnc-eval nightly {logs} --out REPORTS" in err
    assert f"{logs}/*.bag" in err
    assert not (tmp_path / "out").exists()
    (tmp_path / "empty").mkdir()  # a folder without logs still says what a log is
    assert main(["info", str(tmp_path / "empty")]) == 4
    assert "not a ROS 2 bag (no metadata.yaml)" in capsys.readouterr().err


def test_did_you_mean_quotes_only_the_key(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "--set", "slam.loop.enabeld=false"]) == 2
    err = capsys.readouterr().err
    assert "'slam.loop.enabeld' (did you mean slam.loop.enabled?)" in err


def test_a_night_of_only_hidden_logs_says_they_were_skipped(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    logs = tmp_path / "logs"
    (logs / ".recording").mkdir(parents=True)
    (logs / ".recording" / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n", encoding="utf-8")
    shutil.copy(LOG, logs / ".partial.bag")
    assert main(["nightly", str(logs), "--out", str(tmp_path / "out")]) == 4
    err = capsys.readouterr().err
    assert "no logs found" in err
    assert "2 hidden entries skipped (.partial.bag, .recording:" in err
