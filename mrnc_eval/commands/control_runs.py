"""The control verb's two runs as data: a simulation of the laws on the paper's circle (or along a
log's path) and a replay of a recorded run, and the studies a simulation adds to its result
(Table II and its readings, loop gains and margins, disturbance events, RAID's output scale)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mrnc_eval.config import Config
from mrnc_eval.control.closed_loop import ClosedLoopTrace, run_closed_loop
from mrnc_eval.control.margins import bode, loop_summary
from mrnc_eval.control.raid import interior_gain
from mrnc_eval.control.replay import evaluated, replay_roles, replay_trace
from mrnc_eval.control.scenario import Scenario, paper_circle_scenario
from mrnc_eval.data import Waypoints
from mrnc_eval.evaluation.control_run import evaluate_trace, raid_scale_study
from mrnc_eval.evaluation.disturbance import disturbance_study
from mrnc_eval.io.control_recording import read_recording, scenario_from_log
from mrnc_eval.reports.control_tables import (
    disturbance_table,
    paper_reading_table,
    raid_output_table,
    replay_definitions,
    scale_study_table,
    table_notes,
    table_two,
)
from mrnc_eval.results import RunResult
from mrnc_eval.schema import control as K


def simulate(cfg: Config, names: tuple[str, ...],
             scenario: Scenario) -> tuple[dict[str, ClosedLoopTrace], dict[str, Any]]:
    traces = {n: run_closed_loop(scenario, cfg.control, cfg.robot, n) for n in names}
    return traces, {n: evaluate_trace(tr, cfg.control, cfg.robot.track_width_m) for n, tr in traces.items()}


@dataclass(kw_only=True)
class ControlRun:
    """What one simulate or replay produced, before it becomes a RunResult."""

    traces: dict[str, ClosedLoopTrace]
    metrics: dict[str, Any]
    names: tuple[str, ...]
    roles: Mapping[str, str]  # of the log, read once with its streams
    warnings: list[str]
    definitions: list[str]
    scenario: Scenario | None = None  # simulate: the drive, for the RAID scale study
    replay_kind: str = ""  # replay: "path" (following one) or "wheel_speed" (no path)
    t0_stamp_s: float | None = None  # replay: log time of the series' t = 0


def simulated_run(log_path: Path | None, cfg: Config, controllers: tuple[str, ...]) -> ControlRun:
    roles: Mapping[str, str] = {}
    if log_path is None:
        scenario = paper_circle_scenario(cfg.control)
    else:
        scenario, roles = scenario_from_log(log_path, cfg.io, cfg.control)
    traces, metrics = simulate(cfg, controllers, scenario)
    return ControlRun(traces=traces, metrics=metrics, names=controllers, roles=roles, warnings=[],
                      definitions=table_notes(cfg), scenario=scenario)


def replayed_run(log_path: Path, cfg: Config, path: Waypoints | None = None, path_source: str = "") -> ControlRun:
    """Recompute the references the chain would issue along the recorded pose (pure pursuit at its
    rate, inverse kinematics, the same reference slew) and evaluate the recorded wheel speeds and
    pump commands against them. Without a path (none in the log, no `path`): wheel-speed tracking
    against the inverse kinematics of the recorded cmd_vel (or the wheel odometry's twist)."""
    rec = read_recording(log_path, cfg.io, cfg.robot.wheel_radius_m, path, path_source if path is not None else "")
    tr, warnings = replay_trace(rec, cfg.control, cfg.robot)
    return ControlRun(traces={"recorded": tr}, metrics={"recorded": evaluate_trace(tr, cfg.control)},
                      names=("recorded",), roles=replay_roles(rec), warnings=warnings,
                      definitions=replay_definitions(rec, cfg) + table_notes(cfg),
                      replay_kind="path" if rec.waypoints is not None else "wheel_speed",
                      t0_stamp_s=float(rec.speeds.stamps[evaluated(rec)][0]))


def add_simulation_studies(result: RunResult, run: ControlRun, cfg: Config) -> None:
    """Table II and its readings, the loop gains and margins (Bode data), the disturbance events
    and RAID's output-scale study."""
    loops = loop_summary(cfg.control, cfg.control.pure_pursuit.desired_speed_mps)
    result.tables += [paper_reading_table(run.metrics, run.names, cfg), table_two(run.metrics, run.names, cfg),
                      raid_output_table(loops)]
    result.extra["loop"] = loops
    w, loop = bode(cfg.control, interior_gain(cfg.control, v=cfg.control.pure_pursuit.desired_speed_mps, phi=0.0))
    result.series[K.BODE_W] = w
    for law, lw in loop.items():
        result.series[K.bode_magnitude(law)] = 20.0 * np.log10(np.abs(lw))
        result.series[K.bode_phase(law)] = np.degrees(np.unwrap(np.angle(lw)))
    events = disturbance_study(run.names, cfg.control, cfg.robot)
    result.tables.append(disturbance_table(events, cfg))
    result.extra["disturbance"] = events
    if "raid" in run.names and cfg.control.raid.scale_study and run.scenario is not None:
        study = raid_scale_study(run.scenario, cfg.control, cfg.robot, tuple(cfg.control.raid.scale_study))
        result.tables.append(scale_study_table(study, cfg))
        result.extra["raid_scale_study"] = study
