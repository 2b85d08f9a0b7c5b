"""`mrnc-eval control`: closed-loop comparison of controllers (simulate) or evaluation of a
recorded run (replay), with Table II and per-side metrics, written as a RunResult."""

from __future__ import annotations

import logging
import math
import sys
from pathlib import Path

import numpy as np

from mrnc_eval.config import Config, config_hash, dump_config
from mrnc_eval.control.closed_loop import ClosedLoopTrace, run_closed_loop
from mrnc_eval.control.controllers import CONTROLLERS, LABELS, rbf_centres
from mrnc_eval.control.scenario import Scenario, paper_circle_scenario
from mrnc_eval.errors import InputError, UsageError
from mrnc_eval.evaluation.control_metrics import path_metrics, tracking_metrics
from mrnc_eval.results import Event, Metric, RunResult, Table, log_id_for, write_result

log = logging.getLogger(__name__)

UNITS = {"settling_time_s": "s", "overshoot_pct": "%", "steady_state_error_mps": "m/s", "rise_time_s": "s",
         "iae": "m", "ise": "m^2/s", "itae": "m s", "rms_error_mps": "m/s", "max_abs_error_mps": "m/s",
         "funnel_violations": "samples", "max_e_over_o": "", "saturation_ratio": "", "longest_saturation_s": "s",
         "max_abs_command_rpm": "RPM", "control_effort": "RPM^2 s", "total_variation_rpm": "RPM",
         "recovery_time_s": "s", "safety_stops": "", "n_steps": "",
         "cross_track_rms_m": "m", "cross_track_max_m": "m", "cross_track_p95_m": "m",
         "heading_error_rms_rad": "rad", "completion_time_s": "s", "final_position_error_m": "m"}
TABLE_ROWS = [("Settling time (s)", "settling_time_s", "max"), ("Overshoot (%)", "overshoot_pct", "max"),
              ("Steady-state error (m/s)", "steady_state_error_mps", "max"),
              ("Funnel violations", "funnel_violations", "sum"), ("Max |U*| (RPM)", "max_abs_command_rpm", "max"),
              ("Saturation ratio", "saturation_ratio", "max"), ("Safety stops", "safety_stops", "sum"),
              ("Cross-track RMS (m)", "cross_track_rms_m", "path")]


def parse_controllers(text: str) -> tuple[str, ...]:
    names = tuple(n.strip().lower() for n in text.split(",") if n.strip())
    bad = [n for n in names if n not in CONTROLLERS]
    if bad or not names:
        raise UsageError(f"--controllers: unknown {', '.join(bad) or '(none)'}; choose from {', '.join(CONTROLLERS)}")
    return names


def evaluate_trace(tr: ClosedLoopTrace, cfg: Config) -> dict[str, dict[str, float]]:
    """Per side and path metrics of one controller's run."""
    mc = cfg.control.metrics
    out: dict[str, dict[str, float]] = {}
    for side in ("left", "right"):
        m = tracking_metrics(tr.t, getattr(tr, f"v_ref_{side}"), getattr(tr, f"v_wheel_{side}"),
                             getattr(tr, f"u_{side}"), tr.funnel, u_max=cfg.control.actuator.u_max_rpm,
                             slip=getattr(tr, f"slip_{side}"), cfg=mc)
        m["safety_stops"] = sum(1 for e in tr.events if e.get("side") == side)
        out[side] = m
    out["path"] = path_metrics(tr.x, tr.y, tr.yaw, tr.t, tr.waypoints, tr.completed)
    return out


def table_two(per_ctrl: dict[str, dict[str, dict[str, float]]], names: tuple[str, ...]) -> Table:
    cells = []
    for _label, key, agg in TABLE_ROWS:
        row = []
        for n in names:
            m = per_ctrl[n]
            if agg == "path":
                v = m["path"][key]
            else:
                vals = [m[s][key] for s in ("left", "right")]
                v = float(np.nansum(vals)) if agg == "sum" else (float("nan") if all(np.isnan(vals)) else float(np.nanmax(vals)))
            if key in ("funnel_violations", "safety_stops"):
                v = int(v)
            row.append("not settled" if isinstance(v, float) and math.isinf(v) else v)
        cells.append(row)
    return Table(title="Table II: control performance (worst side)", row_labels=[r[0] for r in TABLE_ROWS],
                 column_labels=[LABELS[n] for n in names], cells=cells, best="min", precision=3,
                 notes=["Settling: first time after which |v - v_ref| stays within max(2 % of the step, 0.02 m/s), "
                        "steps = reference ramps of >= 0.1 m/s, evaluated up to 10 s after the ramp; "
                        "overshoot relative to the step; steady-state error = |mean(v_ref - v)| over the last "
                        "min(20 %, 2 s) of each step window (see `mrnc-eval config`, control.metrics).",
                        "APC and FOPTC are stand-ins (CFDL-MFAC; prescribed-time gain): the source papers were "
                        "not available."])


def _scenario_from_log(log_path: Path, cfg: Config) -> Scenario:
    from mrnc_eval.io import open_log

    with open_log(log_path, cfg.io) as lg:
        wp = lg.waypoints().xy
        start = lg.ground_truth() if lg.has_role("ground_truth") else None
    if start is not None:
        q = start.quat_xyzw[0]
        yaw = math.atan2(2 * (q[3] * q[2] + q[0] * q[1]), 1 - 2 * (q[1] ** 2 + q[2] ** 2))
        pose = (float(start.positions[0, 0]), float(start.positions[0, 1]), yaw)
    else:
        pose = (float(wp[0, 0]), float(wp[0, 1]), math.atan2(wp[1, 1] - wp[0, 1], wp[1, 0] - wp[0, 0]))
    base = paper_circle_scenario(cfg.control)
    return Scenario(f"path of {log_path.name}", wp, base.slip_patches, pose)


def simulate(cfg: Config, names: tuple[str, ...], scenario: Scenario) -> tuple[dict, dict]:
    traces = {n: run_closed_loop(scenario, cfg.control, cfg.robot, n) for n in names}
    return traces, {n: evaluate_trace(tr, cfg) for n, tr in traces.items()}


def replay(log_path: Path, cfg: Config) -> tuple[dict, dict]:
    """Recompute the references the chain would issue along the recorded pose, and evaluate
    the recorded wheel speeds and pump commands against them."""
    from mrnc_eval.control.kinematics import inverse_kinematics, slew
    from mrnc_eval.control.pure_pursuit import PurePursuit
    from mrnc_eval.io import open_log

    with open_log(log_path, cfg.io) as lg:
        roles = lg.roles
        for role in ("path", "wheel_speeds"):
            if role not in roles:
                raise InputError(log_path, f"control replay needs a {role} topic (none found; set io.roles.{role})")
        wp = lg.waypoints().xy
        pose = lg.ground_truth() if "ground_truth" in roles else lg.wheel_odometry()
        speeds = lg.wheel_speeds(wheel_radius_m=cfg.robot.wheel_radius_m)
        cmds = lg.commands() if "commands" in roles else None
    q = pose.quat_xyzw
    yaw = np.arctan2(2 * (q[:, 3] * q[:, 2] + q[:, 0] * q[:, 1]), 1 - 2 * (q[:, 1] ** 2 + q[:, 2] ** 2))
    t = speeds.stamps
    px = np.interp(t, pose.stamps, pose.positions[:, 0])
    py = np.interp(t, pose.stamps, pose.positions[:, 1])
    pyaw = np.interp(t, pose.stamps, np.unwrap(yaw))
    pp = PurePursuit(wp, cfg.control.pure_pursuit, cfg.robot.track_width_m, cfg.robot.max_speed_mps)
    v_ref = np.zeros((t.size, 2))
    cmd = np.zeros((t.size, 2))
    next_pp, tl, tr_, vl, vr = t[0], 0.0, 0.0, 0.0, 0.0
    accel = cfg.control.kinematics.reference_accel_limit_mps2
    for k in range(t.size):  # pure pursuit at its own rate along the recorded pose, same reference shaping
        if t[k] >= next_pp:
            v, w, _, _ = pp.step(px[k], py[k], pyaw[k], 0.5 * (speeds.left[k] + speeds.right[k]))
            tl, tr_ = inverse_kinematics(v, w, cfg.robot.track_width_m)
            next_pp = t[k] + 1.0 / cfg.control.pure_pursuit.rate_hz
        dt_k = t[k] - t[k - 1] if k else 0.0
        vl, vr = slew(vl, tl, accel, dt_k), slew(vr, tr_, accel, dt_k)
        v_ref[k] = vl, vr
        cmd[k] = tl, tr_
    f = cfg.control.funnel
    o = (f.o_ov_mps - f.o_b_mps) * np.exp(-f.o_star_per_s * (t - t[0])) + f.o_b_mps
    u_l = np.interp(t, cmds.stamps, cmds.left) if cmds is not None else np.zeros_like(t)
    u_r = np.interp(t, cmds.stamps, cmds.right) if cmds is not None else np.zeros_like(t)
    tr = ClosedLoopTrace("recorded", "recorded", t - t[0], px, py, pyaw, np.zeros_like(t), np.zeros_like(t),
                         np.zeros_like(t), np.zeros_like(t), v_ref[:, 0], v_ref[:, 1], speeds.left, speeds.right,
                         np.zeros_like(t), np.zeros_like(t), u_l, u_r, o, completed=pp.done, waypoints=wp)
    return {"recorded": tr}, {"recorded": evaluate_trace(tr, cfg)}


def run_log(log_path: Path | None, cfg: Config, out_dir: Path, *, mode: str = "replay",
            controllers: tuple[str, ...] = CONTROLLERS) -> RunResult:
    if mode == "simulate":
        scenario = paper_circle_scenario(cfg.control) if log_path is None else _scenario_from_log(log_path, cfg)
        traces, metrics = simulate(cfg, controllers, scenario)
        names = controllers
    elif mode == "replay":
        if log_path is None:
            raise UsageError("control --mode replay needs a LOG")
        traces, metrics = replay(log_path, cfg)
        names = ("recorded",)
    else:
        raise UsageError(f"unknown mode {mode!r}: replay or simulate")
    result = RunResult(kind="control", log_path=str(log_path or "paper-scenario"),
                       log_id=log_id_for(log_path) if log_path else "paper-circle", config_hash=config_hash(cfg))
    first = next(iter(traces.values()))
    result.series["t"] = first.t[:: _decimate(first.t)]
    result.series["path_xy"] = first.waypoints
    result.series["funnel_o"] = first.funnel[:: _decimate(first.t)]
    for n in names:
        tr = traces[n]
        step = _decimate(tr.t)
        for side in ("left", "right"):
            group = f"control/{n}/{side}"
            for key, val in metrics[n][side].items():
                result.metrics.append(Metric(key, val if isinstance(val, int) else float(val), UNITS.get(key, ""), group))
            result.series[f"{n}_{side}_v_ref"] = getattr(tr, f"v_ref_{side}")[::step]
            result.series[f"{n}_{side}_v_meas"] = getattr(tr, f"v_wheel_{side}")[::step]
            result.series[f"{n}_{side}_u_rpm"] = getattr(tr, f"u_{side}")[::step]
        cte = metrics[n]["path"].pop("_cte")
        for key, val in metrics[n]["path"].items():
            result.metrics.append(Metric(key, float(val), UNITS.get(key, ""), f"control/{n}/path"))
        result.series[f"{n}_t"] = tr.t[::step]
        result.series[f"{n}_xy"] = np.c_[tr.x, tr.y][::step]
        result.series[f"{n}_cte_m"] = cte[::step]
        result.events += [Event(e["t_s"], "safety_stop", f"{LABELS.get(n, n)}: {e['message']}", {"side": e["side"]})
                          for e in tr.events]
    if mode == "simulate":
        result.tables.append(table_two(metrics, names))
    result.extra = {"mode": mode, "controllers": list(names), "labels": {n: LABELS.get(n, n) for n in names},
                    "rbf_centres": rbf_centres(cfg.control).tolist(),
                    "saturation_applies_to": cfg.control.actuator.saturation_applies_to,
                    "curvature": cfg.control.pure_pursuit.curvature}
    write_result(result, out_dir, dump_config(cfg))
    return result


def _decimate(t: np.ndarray, max_points: int = 20000) -> int:
    return max(1, t.size // max_points)


def main(log_path: Path | None, cfg: Config, *, mode: str, controllers: str, out: Path, json_out: bool) -> None:
    import datetime as dt

    names = parse_controllers(controllers)
    if log_path is not None and not log_path.exists():
        raise InputError(log_path, "no such file or directory")
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    run_dir = out / f"{log_id_for(log_path) if log_path else 'paper-circle'}-control-{mode}-{stamp}"
    result = run_log(log_path, cfg, run_dir, mode=mode, controllers=names)
    if json_out:
        from mrnc_eval.cli import emit_json
        from mrnc_eval.results import _json_safe

        body: dict = {}
        for m in result.metrics:
            _, ctrl, side = m.group.split("/")
            body.setdefault(ctrl, {}).setdefault(side, {})[m.name] = m.value
        emit_json(_json_safe({"run_dir": str(run_dir), "controllers": body}))
        return
    from mrnc_eval.reports.tables import render_table

    for table in result.tables:
        sys.stdout.write(render_table(table, "markdown"))
    sys.stdout.write(f"results: {run_dir}\n")
