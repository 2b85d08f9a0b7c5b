"""Issue 25 items 2, 5: plants classified by the authority the clamp and the slip leave them, Wilson
95 % intervals, stop causes per run, and the same stop rule for every law (one switch)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from mrnc_eval.commands.control_sweep import run_one, summarise
from mrnc_eval.config import Config
from mrnc_eval.control.closed_loop import ST_IAE, run_closed_loop
from mrnc_eval.control.scenario import paper_circle_scenario
from mrnc_eval.control.sweep import PlantDraw, authority_margin, feasible, plant_for, scenario_for, wilson_interval

# the nominal paper circle: 0.40 m/s anywhere, 0.40 m/s on the 0.15 patch, 0.39 on the 0.18 one (rounded)
DEMANDS = [(0.0, 0.40), (0.15, 0.40), (0.18, 0.39)]
EASY = PlantDraw(0, 0.1, 60.0, 0.04, 0.4, 1.0)  # the default plant
HARD = PlantDraw(1, -0.25, 140.0, 0.04, 0.4, 2.0)  # weak drive, wide dead band, slip x 2


def test_wilson_interval_closed_forms() -> None:
    z2 = 1.959964 ** 2
    assert wilson_interval(0, 10) == pytest.approx((0.0, z2 / (10 + z2)))
    lo, hi = wilson_interval(5, 10)
    assert (lo, hi) == pytest.approx((0.2366, 0.7634), abs=1e-4)
    assert all(math.isnan(v) for v in wilson_interval(0, 0))


def test_feasibility_by_the_static_map_of_the_drive() -> None:
    cfg = Config().control
    # default plant: K = 1.1/3000, (1 - 0.18)(1250 - 60) K = 0.358 m/s against 0.39 -> margin -0.032 > -o_b
    assert authority_margin(EASY, DEMANDS, cfg) == pytest.approx(1.1 / 3000 * 0.82 * 1190 - 0.39, abs=1e-9)
    assert feasible(EASY, DEMANDS, cfg)
    # K = 0.75/3000, slip 0.36: 0.64 x 1110 x K = 0.178 m/s, 0.212 short of 0.39 (o_b = 0.11)
    assert not feasible(HARD, DEMANDS, cfg)
    fb = replace(cfg, actuator=replace(cfg.actuator, saturation_applies_to="feedback"))
    assert feasible(HARD, DEMANDS, fb)  # the clamp on the feedback only leaves f + 1250 RPM


def _run(controller: str, stop_rule: str, draw: PlantDraw, duration_s: float = 20.0):
    c = Config().control
    c = replace(c, plant=plant_for(draw, c), supervisor=replace(c.supervisor, stop_rule=stop_rule))
    return run_closed_loop(scenario_for(draw, paper_circle_scenario(c)), c, Config().robot, controller,
                           duration_s=duration_s, record_every=1)


def test_the_stop_rule_applies_to_every_law_behind_one_switch() -> None:
    """On an infeasible plant PID leaves the funnel; with stop_rule = all it stops there (cause and
    |e|/o recorded); with the paper's rule (RAID only, the negative control) it never stops."""
    parity = _run("pid", "all", HARD)
    paper = _run("pid", "raid_only", HARD)
    assert parity.events
    assert not paper.events
    ev = parity.events[0]
    assert ev["cause"] in ("barrier", "barrier_at_clamp")
    assert ev["e_over_o"] >= 1.0
    assert _run("pid", "all", EASY).events == []  # a feasible plant: PID stays in the funnel


def test_counts_stop_at_a_stop() -> None:
    """IAE runs up to a side's stop: equal to sum |e| dt of the recorded samples before it."""
    tr = _run("raid", "raid_only", HARD)
    assert tr.events
    assert tr.full_rate_stats is not None
    for i, side in enumerate(("left", "right")):
        st = tr.side(side)
        stop = min((e["t_s"] for e in tr.events if e["side"] == side), default=np.inf)
        keep = tr.t < stop
        iae = float(np.sum(np.abs(st.v_wheel - st.v_ref)[keep]) * 1e-3)
        assert tr.full_rate_stats[i, ST_IAE] == pytest.approx(iae, rel=1e-6, abs=1e-9)


def test_sweep_rows_carry_feasibility_and_stop_cause() -> None:
    cfg = Config()
    cfg = replace(cfg, control=replace(cfg.control, sweep=replace(cfg.control.sweep, duration_s=20.0)))
    rows = [run_one(d, n, cfg, 0, DEMANDS) for d in (EASY, HARD) for n in ("raid", "pid")]
    by = {(r.draw, r.controller): r for r in rows}
    assert by[(0, "raid")].feasible
    assert not by[(1, "raid")].feasible
    assert by[(1, "raid")].stop_cause in ("barrier", "barrier_at_clamp")
    assert by[(1, "raid")].stop_side in ("left", "right")
    assert by[(0, "pid")].stop_cause == ""
    s = summarise(rows, ("raid", "pid"), cfg)
    assert s["raid"]["feasible_runs"] == 1
    assert s["raid"]["infeasible_runs"] == 1
    assert s["raid"]["infeasible_safety_stop_fraction"] == 1.0
    assert s["raid"]["infeasible_safety_stop_fraction_ci95"] == pytest.approx(list(wilson_interval(1, 1)))
    assert sum(s["raid"]["stop_causes"].values()) == 1
