"""Metrics of one controller's run (a simulated or replayed ClosedLoopTrace): per side the
segment metrics, the paper reading, the feedback share and RAID's phi-hat; the path metrics when
the run followed a path."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace

import numpy as np

from mrnc_eval.control.closed_loop import SIDES, ST_RESTARTS, ClosedLoopTrace, run_closed_loop
from mrnc_eval.control.config import ControlConfig, RobotGeometry
from mrnc_eval.control.kinematics import inverse_kinematics
from mrnc_eval.control.raid import interior_gain
from mrnc_eval.control.scenario import Scenario
from mrnc_eval.evaluation.control_metrics import feedback_share, paper_metrics, path_metrics, tracking_metrics


def evaluate_trace(tr: ClosedLoopTrace, cfg: ControlConfig,
                   track_width_m: float | None = None) -> dict[str, dict[str, float]]:
    """Per side metrics of one controller's run, and path metrics when it followed a path. With the
    track (m) of a simulated run, also the reference shaping's share of the error against the
    unshaped inverse kinematics of the path follower's command."""
    targets = None
    if track_width_m is not None and np.isfinite(tr.cmd_v).all():
        left, right = inverse_kinematics(tr.cmd_v, tr.cmd_omega, track_width_m)  # type: ignore[arg-type]
        targets = {"left": np.asarray(left), "right": np.asarray(right)}
    mc = cfg.metrics
    out: dict[str, dict[str, float]] = {}
    for i, side in enumerate(SIDES):
        s = tr.side(side)
        stop = min((e["t_s"] for e in tr.events if e.get("side") == side), default=float("inf"))
        # up to a safety stop (at least 3 samples): a stopped side's dead error is not tracking
        keep = tr.t <= max(stop, float(tr.t[min(2, tr.t.size - 1)]))
        t = tr.t[keep]
        m = tracking_metrics(t, s.v_ref[keep], s.v_wheel[keep], s.u[keep], s.funnel[keep],
                             u_max=cfg.actuator.u_max_rpm, slip=s.slip[keep], cfg=mc, o_floor=cfg.funnel.o_b_mps)
        m["time_to_stop_s"] = stop if np.isfinite(stop) else float("nan")
        if targets is not None:  # IAE(r - target) / IAE(v - target): the error the shaping itself adds
            lag = float(np.sum(np.abs(s.v_ref - targets[side])[keep]))
            total = float(np.sum(np.abs(s.v_wheel - targets[side])[keep]))
            m["shaping_share_of_error"] = lag / total if total > 0 else float("nan")
        m["safety_stops"] = sum(1 for e in tr.events if e.get("side") == side)
        if tr.full_rate_stats is not None:  # simulated: restarts of the per-step clocks (funnel anchor, FOPTC)
            m["segment_restarts"] = int(tr.full_rate_stats[i, ST_RESTARTS])
        if s.u_fb is not None:  # simulated: the applied feedback is known
            m["feedback_share_mean"], m["feedback_share_p95"] = feedback_share(s.u[keep], s.u_fb[keep],
                                                                               mc.feedback_share_min_rpm)
        if s.phi is not None and np.isfinite(s.phi).any():
            m["phi_hat_final"], m["phi_hat_max"] = float(s.phi[keep][-1]), float(np.nanmax(np.abs(s.phi)))
        m.update(paper_metrics(t, s.v_ref[keep], s.v_wheel[keep], cfg.paper_metrics))
        out[side] = m
    if tr.waypoints is not None:
        out["path"] = path_metrics(tr.x, tr.y, tr.yaw, tr.waypoints, tr.completion_time_s)
    return out


def raid_scale_study(scenario: Scenario, cfg: ControlConfig, robot: RobotGeometry,
                     scales: tuple[float, ...]) -> list[dict[str, float]]:
    """RAID on `scenario` at each feedback scale (RPM per law unit, the declared output unit kept):
    safety stops, funnel violations, the paper reading's steady-state error, stepinfo overshoot and
    steady offset (worst side), and the interior gain at cruise."""
    rows = []
    for scale in scales:
        c = replace(cfg, raid=replace(cfg.raid, feedback_scale_rpm=float(scale)))
        tr = run_closed_loop(scenario, c, robot, "raid")
        m = evaluate_trace(tr, c, robot.track_width_m)
        sides = [m[s] for s in SIDES]
        rows.append({
            "scale_rpm_per_unit": float(scale),
            "interior_gain_rpm_per_mps": interior_gain(c, v=c.pure_pursuit.desired_speed_mps, phi=0.0),
            "safety_stops": float(sum(s["safety_stops"] for s in sides)),
            "funnel_violations": float(sum(s["funnel_violations"] for s in sides)),
            "paper_steady_state_error_mps": _worst(s["paper_steady_state_error_mps"] for s in sides),
            "paper_stepinfo_overshoot_pct": _worst(s["paper_stepinfo_overshoot_pct"] for s in sides),
            "paper_steady_offset_mps": max((s["paper_steady_offset_mps"] for s in sides), key=abs),
            "stepinfo_overshoot_pct": _worst(s["stepinfo_overshoot_pct"] for s in sides),
        })
    return rows


def _worst(values: Iterable[float]) -> float:
    kept = [v for v in values if not np.isnan(v)]
    return float(max(kept)) if kept else float("nan")
