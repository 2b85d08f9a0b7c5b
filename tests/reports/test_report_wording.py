"""Issue 19, report wording and table files: rounded CSV cells, files named after the paper
table they hold, one Table I with every method, sections and APE cards that name the method, and
a log-health section that does not send the reader to a command that writes nothing."""

from __future__ import annotations

import csv
import re
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


def _slam_run(method: str, config_hash: str) -> RunResult:
    """A SLAM result as the slam verb writes it (the metrics each method has)."""
    names = ["ape_rmse_m", "ape_online_rmse_m", "end_drift_m", "end_drift_online_m", "keyframes", "loop_closures"]
    names += ["imu_time_offset_s", "map_entropy"] if method == "lio" else []  # the peer writes no map
    metrics = [Metric(name=n, value=0.02, unit="m", group="slam/ape") for n in names]
    timing = {st: {"mean": 1.0 if method == "lio" or st in ("read", "matching") else 0.0, "p95": 0.0, "max": 0.0}
              for st in ("read", "deskew", "features", "matching", "graph", "loop")}
    extra = {"method": method, "timing_ms": timing, "deskew": False,
             "warmup_total_ms": 7000.0 if method == "lio" else 0.0}
    return RunResult(kind="slam", log_path="run.mcap", log_id="run", config_hash=config_hash, metrics=metrics,
                     extra=extra)


LIO_ONLY_TEXT = ("re-anchored", "warm-up", "IMU time offset", ">keyframes<", ">loop closures<", ", online (m)<")


def test_two_slam_runs_show_no_control_cards_own_definitions_and_both_config_hashes() -> None:
    html = render_html([_slam_run("lio", "aaaa1111"), _slam_run("kiss-icp", "bbbb2222")], gates=GatesConfig(),
                       config_text="", configs={"aaaa1111": "", "bbbb2222": "slam:\n  method: kiss-icp\n"})
    cards = re.findall(r'<div class="l">([^<]+)</div><div class="v">', html)
    assert cards == ["APE RMSE (lio)", "APE RMSE (kiss-icp)"]  # no funnel, saturation or safety-stop cards
    header = html.split('<p class="meta">')[1].split("</p>")[0]
    assert "configs aaaa1111 (SLAM lio), bbbb2222 (SLAM kiss-icp)" in header  # both hashes, which run used which
    lio, kiss = html.split("<h2>SLAM (kiss-icp)</h2>")
    lio = lio.split("<h2>SLAM (lio)</h2>")[1]
    kiss = kiss.split("<h2>Configuration</h2>")[0]
    for text in LIO_ONLY_TEXT:
        assert text in lio, text  # the LIO section defines them (the negative control of the check below)
        assert text not in kiss, text
    assert "online equals smoothed" in kiss
    assert "<code>slam.method</code></td><td>kiss-icp</td><td>lio</td>" in html  # the one key that differs


def test_a_result_without_config_yaml_does_not_claim_the_defaults() -> None:
    html = render_html([_slam_run("lio", "aaaa1111")], gates=GatesConfig(), config_text="")
    assert "Configuration <code>aaaa1111</code>: no config.yaml beside the result" in html
    assert "the defaults." not in html


def test_control_cards_come_with_a_control_run() -> None:
    html = render_html([_slam_run("lio", "aaaa1111"), _control()], gates=GatesConfig(), config_text="")
    cards = re.findall(r'<div class="l">([^<]+)</div><div class="v">', html)
    assert cards == ["APE RMSE (lio)", "Funnel violations", "Saturation ratio", "Safety stops"]


def test_config_differences_list_only_keys_away_from_the_defaults() -> None:
    from mrnc_eval.config import Config, dump_config, replace_path
    from mrnc_eval.reports.render import config_differences

    assert config_differences(dump_config(Config())) == []
    changed = replace_path(replace_path(Config(), "slam.loop.enabled", False), "slam.mapping_interval_s", 0.3)
    assert config_differences(dump_config(changed)) == [("slam.loop.enabled", "False", "True"),
                                                        ("slam.mapping_interval_s", "0.3", "0.15")]
    older = "slam:\n  loop:\n    enabled: false\n"  # a config.yaml of a release before most keys existed
    assert config_differences(older) == [("slam.loop.enabled", "False", "True")]


def test_trend_titles_name_metrics_with_units() -> None:
    from mrnc_eval.reports.night import metric_label, render_trends

    assert metric_label("slam/ape/ape_rmse_m") == "APE RMSE, smoothed (m)"
    assert metric_label("control/recorded/left/rms_error_mps") == "RMS error (m/s), recorded left"
    assert metric_label("slam/timing/ms_per_sweep_matching") == "matching time per sweep (ms)"
    assert metric_label("slam/mapping_rate_hz") == "mapping rate (Hz)"
    page = render_trends(["2026-11-01", "2026-11-02"], {"slam/ape/ape_rmse_m": {"a": {"2026-11-01": 0.1,
                                                                                     "2026-11-02": 0.2}}},
                         {}, 5, 0.2)
    assert "<figcaption>APE RMSE, smoothed (m) <code>slam/ape/ape_rmse_m</code></figcaption>" in page
