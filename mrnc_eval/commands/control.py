"""`mrnc-eval control`: closed-loop comparison of controllers (simulate), evaluation of a recorded
run (replay) or the robustness sweep, written as a RunResult. Glue only: the loop and the replay
are in control/, the metrics in evaluation/, the tables in reports/control_tables.py."""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from mrnc_eval.commands.control_runs import ControlRun, add_simulation_studies, replayed_run, simulated_run
from mrnc_eval.config import Config, config_hash, dump_config
from mrnc_eval.control.closed_loop import SIDES, ClosedLoopTrace
from mrnc_eval.control.config import shaping_text
from mrnc_eval.control.controllers import CONTROLLERS, LABELS
from mrnc_eval.control.raid import rbf_centres
from mrnc_eval.data import Waypoints
from mrnc_eval.errors import InputError, UsageError
from mrnc_eval.io.split_logs import split_log_paths
from mrnc_eval.io.waypoint_files import read_waypoints
from mrnc_eval.reports.control_tables import (
    UNITS,
    print_summary,
)
from mrnc_eval.results import (
    Event,
    Metric,
    RunResult,
    absolute_log_path,
    check_output_root,
    link_latest,
    log_id_for,
    new_run_dir,
    write_result,
)
from mrnc_eval.schema import control as K

log = logging.getLogger(__name__)


def parse_controllers(text: str) -> tuple[str, ...]:
    names = tuple(n.strip().lower() for n in text.split(",") if n.strip())
    bad = [n for n in names if n not in CONTROLLERS]
    if bad or not names:
        raise UsageError(f"--controllers: unknown {', '.join(bad) or '(none)'}; choose from {', '.join(CONTROLLERS)}")
    return names



def simulation_topics(roles: Mapping[str, str]) -> dict[str, str]:
    """role -> topic of what a simulation along the log's path reads, for summaries and reports
    (a replay names every role it read)."""
    return {r: roles[r] for r in ("path", "ground_truth") if r in roles}


def run_log(log_path: Path | None, cfg: Config, out_dir: Path, *, mode: str = "replay",
            controllers: tuple[str, ...] = CONTROLLERS, log_id: str | None = None,
            path: Waypoints | None = None, path_source: str = "--path") -> RunResult:
    """`log_id` names the log in results (default: from its file name; the nightly job passes its own);
    `path` (replay: waypoints from --path, named `path_source`) replaces the log's path topic."""
    wall_start = time.perf_counter()  # the run's real time: JUnit's time of the control gates
    if path is not None and mode != "replay":
        raise UsageError("--path supplies the path of a replay (--mode replay)")
    if mode == "simulate":
        run = simulated_run(log_path, cfg, controllers)
    elif mode == "replay":
        if log_path is None:
            raise UsageError("control --mode replay needs a LOG")
        run = replayed_run(log_path, cfg, path, path_source)
    else:
        raise UsageError(f"unknown mode {mode!r}: replay, simulate, sweep, identify or tune")
    result = RunResult(kind="control", log_path=absolute_log_path(log_path) if log_path else "paper-scenario",
                       log_id=log_id or (log_id_for(log_path) if log_path else "paper-circle"),
                       config_hash=config_hash(cfg), warnings=run.warnings)
    _add_runs(result, run, mode, cfg)
    if mode == "simulate":
        add_simulation_studies(result, run, cfg)
    if run.replay_kind:
        result.extra[K.REPLAY] = run.replay_kind
        result.extra[K.T0_STAMP_S] = run.t0_stamp_s
    result.extra["wall_s"] = time.perf_counter() - wall_start  # real time: JUnit's time of the control gates
    write_result(result, out_dir, dump_config(cfg))
    return result


def _add_runs(result: RunResult, run: ControlRun, mode: str, cfg: Config) -> None:
    """Every controller's series and metrics, the run-start funnel and what the run was."""
    longest = max(run.traces.values(), key=lambda tr: tr.t.size)  # run-start funnel: the same o(t) for all
    result.series[K.T] = longest.t[:: _decimate(longest.t)]
    if longest.waypoints is not None:
        result.series[K.PATH_XY] = longest.waypoints
    result.series[K.FUNNEL_O] = longest.funnel[:: _decimate(longest.t)]
    for n in run.names:
        _add_controller(result, n, run.traces[n], run.metrics[n])
    result.extra = {K.MODE: mode, K.CONTROLLERS: list(run.names),
                    K.LABELS: {n: run.traces[n].label if n == "recorded" else LABELS.get(n, n) for n in run.names},
                    "rbf_centres": rbf_centres(cfg.control).tolist(), "rbf_centre_seed": cfg.control.raid.centre_seed,
                    "seed": cfg.control.seed, K.DEFINITIONS: run.definitions,
                    K.SATURATION_APPLIES_TO: cfg.control.actuator.saturation_applies_to,
                    "supervisor": cfg.control.supervisor.stop_rule, "step_detector": cfg.control.steps.detector,
                    "reference_shaping": shaping_text(cfg.control),
                    K.CURVATURE: cfg.control.pure_pursuit.curvature,
                    K.ROLES: dict(run.roles) if mode == "replay" else simulation_topics(run.roles)}



def _add_controller(result: RunResult, name: str, tr: ClosedLoopTrace, metrics: dict[str, Any]) -> None:
    """One controller's metrics (per side and path), decimated series and safety stops into `result`."""
    step = _decimate(tr.t)
    for side in SIDES:
        group = f"control/{name}/{side}"
        s = tr.side(side)
        for key, val in metrics[side].items():
            value = val if isinstance(val, int) else float(val)
            result.metrics.append(Metric(name=key, value=value, unit=UNITS.get(key, ""), group=group))
        result.series[K.side_series(name, side, K.V_REF)] = s.v_ref[::step]
        result.series[K.side_series(name, side, K.V_MEAS)] = s.v_wheel[::step]
        result.series[K.side_series(name, side, K.U_RPM)] = s.u[::step]
        for key, series in ((K.side_series(name, side, K.U_FB_RPM), s.u_fb),
                            (K.side_series(name, side, K.PHI_HAT), s.phi)):
            if series is not None and np.isfinite(series).any():
                result.series[key] = series[::step]
    result.series[K.time(name)] = tr.t[::step]
    if np.isfinite(tr.x).any():  # wheel-speed tracking without a pose topic: nowhere to place the run
        result.series[K.driven_xy(name)] = np.c_[tr.x, tr.y][::step]
    if "path" in metrics:
        cte = metrics["path"].pop("_cte")
        for key, val in metrics["path"].items():
            result.metrics.append(Metric(name=key, value=float(val), unit=UNITS.get(key, ""),
                                         group=f"control/{name}/path"))
        result.series[K.cte(name)] = cte[::step]
    result.series[K.funnel(name)] = tr.funnel[::step]
    result.events += [Event(t_s=e["t_s"], kind="safety_stop", message=f"{LABELS.get(name, name)}: {e['message']}",
                            data={"side": e["side"]}) for e in tr.events]


def _decimate(t: np.ndarray, max_points: int = 20000) -> int:
    return max(1, t.size // max_points)


CONTROL_OUTPUT_BYTES = 50_000_000  # free space asked for before a run: result.json, series.npz


def main(log_path: Path | None, cfg: Config, *, mode: str, controllers: str | None, out: Path, json_out: bool,
         runs: int | None = None, seed: int | None = None, path_file: Path | None = None) -> None:
    if controllers is not None and mode == "replay":  # refused, not silently ignored
        raise UsageError("--controllers chooses the controllers of --mode simulate and sweep; a replay evaluates "
                         "the recorded run (the deployed controller)")
    names = parse_controllers(controllers) if controllers is not None else CONTROLLERS
    if path_file is not None and mode != "replay":
        raise UsageError("--path supplies the path of a replay (--mode replay)")
    if log_path is not None and split_log_paths(log_path) is None and not log_path.exists():  # split: open_log checks
        raise InputError(log_path, "no such file or directory")
    waypoints = read_waypoints(path_file) if path_file is not None else None  # a bad file fails before any output
    check_output_root(out, need_bytes=CONTROL_OUTPUT_BYTES)  # before the long work, not after it
    run_dir = new_run_dir(out, log_id_for(log_path) if log_path else "paper-circle", f"control-{mode}")
    if mode == "tune":
        if log_path is not None:
            raise UsageError("control --mode tune runs the paper circle's nominal plant; it takes no LOG")
        from mrnc_eval.commands.control_tune import run_tune

        result = run_tune(cfg, names, run_dir)
    elif mode == "identify":
        if log_path is None:
            raise UsageError("control --mode identify needs a LOG with pump commands and wheel speeds")
        from mrnc_eval.commands.control_identify import run_identify

        result = run_identify(log_path, cfg, run_dir)
    elif mode == "sweep":
        if log_path is not None:
            raise UsageError("control --mode sweep runs the paper circle; it takes no LOG")
        from mrnc_eval.commands.control_sweep import run_sweep_result

        result = run_sweep_result(cfg, names, run_dir, runs=runs, seed=seed)
    else:
        result = run_log(log_path, cfg, run_dir, mode=mode, controllers=names, path=waypoints,
                         path_source=f"{path_file} (--path)")
    link_latest(run_dir)
    if json_out:
        from mrnc_eval.commands.output import emit_document

        emit_document(json_body(result, run_dir, mode))
        return
    print_summary(result, run_dir)


def json_body(result: RunResult, run_dir: Path, mode: str) -> dict[str, Any]:
    """The --json document (commands/output.py): one `results` item per controller and side
    (simulate, replay; RAID's phi-hat(t) at about 1 Hz beside its stats) or per controller (sweep)."""
    from mrnc_eval.commands.output import document, item, split_stats

    meta = {"run_dir": str(run_dir), "mode": mode, "labels": result.extra["labels"],
            "definitions": result.extra["definitions"]}
    if mode == "tune":  # one item per law: the gains found (stats) and where the search started
        table = result.tables[0]
        items = [item(law, {**r["params"], "cost": r["cost"], "start_cost": r["start_cost"],
                            "evaluations": r["evaluations"]}, controller=law, start_params=r["start_params"],
                      box=r["box"]) for law, r in result.extra["tuned"].items()]
        return document("control", items, meta={**meta, **{k: result.extra[k] for k in (
            "optimiser", "cost", "budget", "tuning_noise_seed", "report_noise_seed")},
            "table": {"rows": table.row_labels, "columns": table.column_labels, "cells": table.cells}},
            warnings=result.warnings)
    if mode == "identify":  # one item per side
        items = [item(side, est, side=side) for side, est in result.extra["identified"].items()]
        return document("control", items, meta={**meta, "plant_file": str(run_dir / result.extra["plant_file"]),
                                                "topics": result.extra["roles"]}, warnings=result.warnings)
    if mode == "sweep":
        items = []
        for ctrl, summary in result.extra["sweep"].items():
            stats, rest = split_stats(summary)
            items.append(item(ctrl, stats, controller=ctrl, **rest))
        return document("control", items, meta={**meta, "runs": result.extra["runs"], "seed": result.extra["seed"],
                                                    "supervisor": result.extra.get("supervisor", ""),
                                                    "reference_shaping": result.extra.get("shaping", "")},
                        warnings=result.warnings)
    body: dict[tuple[str, str], dict[str, Any]] = {}
    for m in result.metrics:
        _, ctrl, side = m.group.split("/")
        body.setdefault((ctrl, side), {})[m.name] = m.value
    items = []
    for (ctrl, side), stats in body.items():
        extra: dict[str, Any] = {}
        t, phi = result.series.get(K.time(ctrl)), result.series.get(K.side_series(ctrl, side, K.PHI_HAT))
        if phi is not None and t is not None:
            every = max(1, int(round(1.0 / max(float(np.median(np.diff(t))), 1e-9))))
            extra["phi_hat"] = {"t_s": t[::every].tolist(), "value": phi[::every].tolist()}
        items.append(item(f"{ctrl}/{side}", stats, controller=ctrl, side=side, **extra))
    study: dict[str, Any] = {k: result.extra[k] for k in ("loop", "raid_scale_study", "disturbance",
                                                          "reference_shaping", "supervisor", "step_detector")
                             if k in result.extra}
    return document("control", items, meta={**meta, **study, "events": [e.__dict__ for e in result.events]},
                    warnings=result.warnings)

