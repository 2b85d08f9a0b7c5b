"""Issue 25 item 6: equal-effort tuning. Every law gets the same optimiser, cost and budget; the
configured gains are the first candidate, so the tuned cost never exceeds it; a deliberately bad PID
(k_p 100, k_i 10) is improved (the search works); the CLI records the gains found for every law."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from mrnc_eval.cli import main
from mrnc_eval.config import Config
from mrnc_eval.control.scenario import paper_circle_scenario
from mrnc_eval.control.tune import SPACE, tune_law


def test_same_budget_and_never_worse_than_the_start() -> None:
    cfg = Config()
    sc = paper_circle_scenario(cfg.control)
    for law in SPACE:
        r = tune_law(law, sc, cfg.control, cfg.robot, budget=4, seed=0, duration_s=15.0, noise_seed=1)
        assert r.evaluations == 4
        assert r.cost <= r.start_cost
        assert set(r.params) == {f"{s}.{n}" for s, n, *_ in SPACE[law]}


def test_the_search_improves_a_bad_start() -> None:
    cfg = Config()
    c = replace(cfg.control, pid=replace(cfg.control.pid, kp=100.0, ki=10.0))
    r = tune_law("pid", paper_circle_scenario(c), c, cfg.robot, budget=6, seed=0, duration_s=15.0, noise_seed=1)
    assert r.cost < 0.8 * r.start_cost
    assert r.params["pid.kp"] > 100.0


def test_tune_cli_records_every_law(tmp_path, capsys) -> None:
    assert main(["control", "--mode", "tune", "--controllers", "raid,pid,ff", "--json", "--out", str(tmp_path),
                 "--set", "control.tune.budget=3", "--set", "control.tune.duration_s=15"]) == 0
    body = json.loads(capsys.readouterr().out)
    tuned = {r["controller"]: r for r in body["results"]}
    meta = body["meta"]
    assert set(tuned) == {"raid", "pid"}  # ff has nothing to tune
    assert meta["budget"] == 3
    assert {r["stats"]["evaluations"] for r in tuned.values()} == {3}
    assert "raid.feedback_scale_rpm" in tuned["raid"]["stats"]
    assert "raid.beta" in tuned["raid"]["stats"]
    assert tuned["raid"]["start_params"]["raid.beta"] == 1.2
    assert meta["tuning_noise_seed"] != meta["report_noise_seed"]
    assert meta["table"]["columns"] == ["RAID: paper", "RAID: tuned", "PID: paper", "PID: tuned"]
    assert meta["table"]["cells"][0][0] == pytest.approx(2.42, abs=0.1)  # RAID's stepinfo settling, paper gains
