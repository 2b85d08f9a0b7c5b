"""`mrnc-eval compare`: two control replays of one log that differ in one `--set` value, and two
nights of a history."""

from __future__ import annotations

from pathlib import Path

import pytest

from mrnc_eval.cli import main
from mrnc_eval.results import read_result
from tests.export.conftest import Runs

FLOOR = "control.funnel.o_b_mps"


@pytest.fixture(scope="module")
def two_runs(sim_runs: Runs, tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("compare")
    dirs = []
    for name, value in (("a", 0.11), ("b", 0.05)):
        assert main(["control", str(sim_runs.log), "--mode", "replay", "--out", str(root / name),
                     "--set", f"{FLOOR}={value}", "--json"]) == 0
        (run,) = [p for p in (root / name).iterdir() if not p.is_symlink()]  # and OUT/latest -> it
        dirs.append(run)
    return dirs[0], dirs[1]


def test_compare_shows_metrics_side_by_side_and_the_one_config_key(two_runs, tmp_path: Path, capsys,
                                                                   monkeypatch) -> None:
    a, b = two_runs
    monkeypatch.setenv("COLUMNS", "200")  # a terminal wide enough for the whole table
    capsys.readouterr()
    assert main(["compare", str(a), str(b), "--format", "markdown"]) == 0
    text = capsys.readouterr().out
    ra, rb = read_result(a), read_result(b)
    ma = {f"{m.group}/{m.name}": m.value for m in ra.metrics}
    mb = {f"{m.group}/{m.name}": m.value for m in rb.metrics}
    key = "control/recorded/left/max_e_over_o"
    assert ma[key] != mb[key]  # a lower funnel floor changes |e|/o
    row = next(line for line in text.splitlines() if line.startswith(f"| {key} "))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert float(cells[2]) == pytest.approx(ma[key], abs=1e-4)
    assert float(cells[3]) == pytest.approx(mb[key], abs=1e-4)
    assert float(cells[4]) == pytest.approx(mb[key] - ma[key], abs=2e-4)
    assert cells[6] == "worse"  # lower is better: the tighter funnel gives a larger ratio
    config_rows = [line for line in text.split("Configuration keys that differ", 1)[1].splitlines()
                   if line.startswith("|") and line.split("|")[1].strip() and "---" not in line]  # body rows
    assert [c.split("|")[1].strip() for c in config_rows] == [FLOOR]
    assert "0.11" in config_rows[0]
    assert "0.05" in config_rows[0]
    assert main(["compare", str(a), str(b)]) == 0  # the terminal table (rich)
    terminal = capsys.readouterr().out
    assert key in terminal
    assert FLOOR in terminal
    html = tmp_path / "cmp.html"
    assert main(["compare", str(a), str(b), "--out", str(html)]) == 0
    page = html.read_text(encoding="utf-8")
    assert page.startswith("<!DOCTYPE html>")
    assert FLOOR in page
    assert key in page


def test_a_run_compared_with_itself_changes_nothing(two_runs, capsys) -> None:
    a, _ = two_runs
    capsys.readouterr()
    assert main(["compare", str(a), str(a), "--format", "markdown"]) == 0
    text = capsys.readouterr().out
    metric_rows = [line for line in text.split("Configuration", 1)[0].splitlines() if line.startswith("| control/")]
    assert metric_rows
    missing = "| \u2013 |"  # an en dash: no number on either side (NaN, not settled)
    assert all(line.rstrip("| ").endswith("same") or missing in line for line in metric_rows)
    assert "| control." not in text.split("Configuration keys that differ", 1)[1]


def test_compare_two_nights_from_the_history(tmp_path: Path, capsys) -> None:
    from mrnc_eval.history import History, LogRecord

    history = History(tmp_path / "history.sqlite")
    for night, ape in (("2026-11-20", 0.05), ("2026-11-21", 0.08)):
        history.record(LogRecord(night, "yard", "r", "yard.mcap", "0", "h", "ok", "", "t",
                                 (("slam/ape/ape_rmse_m", ape, "m"), ("slam/rtf", 3.0, ""))))
    assert main(["compare", "--history", str(tmp_path), "--nights", "2026-11-20", "2026-11-21",
                 "--format", "markdown"]) == 0
    text = capsys.readouterr().out
    row = next(line for line in text.splitlines() if "yard: slam/ape/ape_rmse_m" in line)
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert [float(cells[2]), float(cells[3]), float(cells[4])] == pytest.approx([0.05, 0.08, 0.03])
    assert main(["compare", "--history", str(tmp_path), "--nights", "2026-11-20", "2026-11-19"]) == 4
