"""Issue 25 item 3: reference shaping as a named option. Without shaping (as the paper) the start-up
step puts |e(0)| = 0.38 m/s beyond o(0) = 0.30 m/s and RAID stops at once; the slew avoids that at
the price of a ramp error (its share is reported); the rate feed-forward removes most of the lag."""

from __future__ import annotations

from dataclasses import replace

from mrnc_eval.config import Config
from mrnc_eval.control.closed_loop import run_closed_loop
from mrnc_eval.control.config import shaping_text
from mrnc_eval.control.scenario import paper_circle_scenario
from mrnc_eval.evaluation.control_run import evaluate_trace


def _run(law: str, shaping: str):
    cfg = Config()
    c = replace(cfg.control, kinematics=replace(cfg.control.kinematics, reference_shaping=shaping))
    tr = run_closed_loop(paper_circle_scenario(c), c, cfg.robot, law, duration_s=9.0)
    return tr, evaluate_trace(tr, c, cfg.robot.track_width_m), c


def test_without_shaping_raid_stops_at_the_start() -> None:
    tr, _, c = _run("raid", "none")
    assert {e["side"] for e in tr.events} == {"left", "right"}
    assert all(e["t_s"] < 0.01 for e in tr.events)
    assert "none" in shaping_text(c)
    tr, m, c = _run("raid", "slew")
    assert not tr.events
    assert m["left"]["shaping_share_of_error"] > 0.05  # the slew's own lag is part of the error
    assert "slew 0.3" in shaping_text(c)


def test_rate_feedforward_shortens_the_start_up() -> None:
    _, slew, _ = _run("pid", "slew")
    _, rate, c = _run("pid", "slew_rate_ff")
    assert "rate feed-forward" in shaping_text(c)
    for side in ("left", "right"):
        assert rate[side]["paper_stepinfo_settling_time_s"] < 0.8 * slew[side]["paper_stepinfo_settling_time_s"]
        assert rate[side]["paper_stepinfo_overshoot_pct"] < slew[side]["paper_stepinfo_overshoot_pct"]
