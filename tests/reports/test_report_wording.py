"""Issue 19, report wording and table files: rounded CSV cells, files named after the paper
table they hold, one Table I with every method, sections and APE cards that name the method, and
a log-health section that does not send the reader to a command that writes nothing."""

from __future__ import annotations

import csv
from pathlib import Path

from mrnc_eval.evaluation.config import GatesConfig
from mrnc_eval.reports.render import render_html, write_report
from mrnc_eval.reports.tables import render_table
from mrnc_eval.results import Metric, RunResult, Table


def _slam(method: str, rmse: float) -> RunResult:
    table = Table("APE RMSE (SE(3) aligned)", ["run", "Mean"], [method], [[rmse], [rmse]], unit="m")
    return RunResult(kind="slam", log_path="run.mcap", log_id="run",
                     metrics=[Metric(name="ape_rmse_m", value=rmse, unit="m", group="slam/ape")],
                     tables=[table], extra={"method": method, "roles": {"lidar": "/ouster/points"}})


def _control() -> RunResult:
    table = Table("Table II: control performance metrics", ["Settling time (s)", "Overshoot (%)"], ["RAID"],
                  [[9.900000095367432], [1.2345678]])
    return RunResult(kind="control", log_path="run.mcap", log_id="run", tables=[table],
                     extra={"mode": "simulate", "controllers": []})


def test_csv_cells_are_rounded_by_unit() -> None:
    rows = list(csv.reader(render_table(_control().tables[0], "csv").splitlines()))
    assert rows[1] == ["Settling time (s)", "9.9"]
    assert rows[2] == ["Overshoot (%)", "1.23"]
    metres = Table("APE", ["seq (old)"], ["lio"], [[0.0122000004]], unit="m")
    assert list(csv.reader(render_table(metres, "csv").splitlines()))[1] == ["seq (old)", "0.0122"]


def test_table_files_are_named_after_their_table_and_hold_every_method(tmp_path: Path) -> None:
    written = write_report([_slam("lio", 0.0122), _slam("kiss-icp", 0.031), _control()], tmp_path,
                           gates=GatesConfig(), config_text="")
    assert {"slam_table1.csv", "control_table2.csv"} <= set(written)
    assert not (tmp_path / "control_table1.csv").exists()
    rows = list(csv.reader((tmp_path / "slam_table1.csv").read_text(encoding="utf-8").splitlines()))
    assert rows[0][1:] == ["lio", "kiss-icp"]
    assert rows[1] == ["run", "0.0122", "0.031"]


def test_sections_and_ape_cards_name_the_method() -> None:
    html = render_html([_slam("lio", 0.0122), _slam("kiss-icp", 0.31)], gates=GatesConfig(), config_text="")
    assert "<h2>SLAM (lio)</h2>" in html
    assert "<h2>SLAM (kiss-icp)</h2>" in html
    assert "APE RMSE (lio)" in html
    assert "APE RMSE (kiss-icp)" in html


def test_log_health_names_the_topics_used_and_no_command_that_writes_nothing() -> None:
    html = render_html([_slam("lio", 0.0122)], gates=GatesConfig(), config_text="")
    assert "run <code>mrnc-eval info</code>" not in html
    assert "Topics used: lidar = <code>/ouster/points</code>" in html


def test_report_exits_1_when_a_gate_fails(tmp_path: Path) -> None:
    from mrnc_eval.cli import main
    from mrnc_eval.config import Config, dump_config
    from mrnc_eval.results import write_result

    limit = Config().gates.ape_rmse_max_m
    for name, rmse, code in (("good", limit / 2, 0), ("bad", limit * 2, 1)):
        run = write_result(_slam("lio", rmse), tmp_path / name, dump_config(Config()))
        assert main(["report", str(run)]) == code, name
