"""Metrics of one controller's run (a simulated or replayed ClosedLoopTrace): per side the
segment metrics, the paper reading, the feedback share and RAID's phi-hat; the path metrics when
the run followed a path."""

from __future__ import annotations

import numpy as np

from mrnc_eval.control.closed_loop import SIDES, ST_RESTARTS, ClosedLoopTrace
from mrnc_eval.control.config import ControlConfig
from mrnc_eval.evaluation.control_metrics import feedback_share, paper_metrics, path_metrics, tracking_metrics


def evaluate_trace(tr: ClosedLoopTrace, cfg: ControlConfig) -> dict[str, dict[str, float]]:
    """Per side metrics of one controller's run, and path metrics when it followed a path."""
    mc = cfg.metrics
    out: dict[str, dict[str, float]] = {}
    for i, side in enumerate(SIDES):
        s = tr.side(side)
        m = tracking_metrics(tr.t, s.v_ref, s.v_wheel, s.u, s.funnel, u_max=cfg.actuator.u_max_rpm, slip=s.slip,
                             cfg=mc)
        m["safety_stops"] = sum(1 for e in tr.events if e.get("side") == side)
        if tr.full_rate_stats is not None:  # simulated: restarts of the per-step clocks (funnel anchor, FOPTC)
            m["segment_restarts"] = int(tr.full_rate_stats[i, ST_RESTARTS])
        if s.u_fb is not None:  # simulated: the applied feedback is known
            m["feedback_share_mean"], m["feedback_share_p95"] = feedback_share(s.u, s.u_fb, mc.feedback_share_min_rpm)
        if s.phi is not None and np.isfinite(s.phi).any():
            m["phi_hat_final"], m["phi_hat_max"] = float(s.phi[-1]), float(np.nanmax(np.abs(s.phi)))
        m.update(paper_metrics(tr.t, s.v_ref, s.v_wheel, cfg.paper_metrics))
        out[side] = m
    if tr.waypoints is not None:
        out["path"] = path_metrics(tr.x, tr.y, tr.yaw, tr.waypoints, tr.completion_time_s)
    return out
