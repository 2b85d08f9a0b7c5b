"""Isolated events on a straight line (issue 25 item 8): the start-up reference step, then a slip
patch entered and left at cruise, per law: stepinfo settling and overshoot of the step, recovery
time per slip event, and the minimum funnel margin 1 - max |e|/o(t) (worst side)."""

from __future__ import annotations

from typing import Any

import numpy as np

from mrnc_eval.control.closed_loop import SIDES, run_closed_loop
from mrnc_eval.control.config import ControlConfig, RobotGeometry
from mrnc_eval.control.plant import SlipPatch
from mrnc_eval.control.scenario import Scenario, waypoint_scenario
from mrnc_eval.evaluation.control_metrics import paper_metrics, recovery_events

LINE_M = 30.0  # straight line length, m
PATCH = SlipPatch(14.0, 0.0, 3.0, 0.15)  # on the line from x = 11 to 17 m, slip 0.15


def line_with_patch(slip: float = PATCH.slip) -> Scenario:
    sc = waypoint_scenario(np.c_[np.linspace(0.0, LINE_M, 16), np.zeros(16)], "line")
    return Scenario("line with a slip patch", sc.waypoints_xy, (SlipPatch(PATCH.x, PATCH.y, PATCH.radius_m, slip),),
                    sc.start_pose)


def disturbance_study(names: tuple[str, ...], cfg: ControlConfig, robot: RobotGeometry) -> dict[str, dict[str, Any]]:
    """Per law: the step and slip-event numbers on the straight line (worst side)."""
    sc = line_with_patch()
    out: dict[str, dict[str, Any]] = {}
    for name in names:
        tr = run_closed_loop(sc, cfg, robot, name)
        m = cfg.metrics
        row: dict[str, Any] = {"safety_stops": len(tr.events)}
        settle, os, margin = [], [], []
        events: dict[str, float] = {}
        for side in SIDES:
            s = tr.side(side)
            p = paper_metrics(tr.t, s.v_ref, s.v_wheel, cfg.paper_metrics)
            settle.append(p["paper_stepinfo_settling_time_s"])
            os.append(p["paper_stepinfo_overshoot_pct"])
            margin.append(1.0 - float(np.max(np.abs(s.v_wheel - s.v_ref) / s.funnel)))
            for _t, kind, rec in recovery_events(tr.t, np.abs(s.v_wheel - s.v_ref), s.slip, m.recovery_band_mps,
                                                 m.recovery_hold_s, m.recovery_horizon_s):
                events[kind] = max(events.get(kind, 0.0), rec)
        row.update({"step_settling_stepinfo_s": float(np.nanmax(settle)), "step_overshoot_stepinfo_pct":
                    float(np.nanmax(os)), "recovery_slip_on_s": events.get("slip on", float("nan")),
                    "recovery_slip_off_s": events.get("slip off", float("nan")), "min_funnel_margin": min(margin)})
        out[name] = row
    return out
