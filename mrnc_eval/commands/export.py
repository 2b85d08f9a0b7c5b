"""`mrnc-eval export RUN_DIR... --mcap OUT.mcap`: one log's results (and optionally its sensor
topics) as one MCAP file for Foxglove / Lichtblick, on the original log's timeline.

Reads result directories only (never recomputes a metric); the log itself is read for the
ground truth, the time origin of a control replay and `--with-log`. The file is written under
a temporary name beside OUT and renamed into place when complete; an existing OUT follows the
one overwrite rule (mrnc_eval/outputs.py): refused, `--force` replaces only an export this tool
wrote, never the log or ground truth a run read."""

from __future__ import annotations

import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mrnc_eval.config import CONFIG_FILE_NAME, Config, load_config
from mrnc_eval.data import Trajectory
from mrnc_eval.errors import EvaluationError, InputError, UsageError
from mrnc_eval.export import topics
from mrnc_eval.export.mcap_file import JsonMcap, stamp_ns
from mrnc_eval.outputs import claim_output, output_file
from mrnc_eval.results import RunResult, read_result
from mrnc_eval.schema import control as control_keys
from mrnc_eval.schema import slam as slam_keys
from mrnc_eval.text import printable


@dataclass(kw_only=True)
class ExportSummary:
    path: Path
    size_bytes: int = 0
    counts: Counter[str] = field(default_factory=Counter)  # messages per topic
    map_points: int = 0
    warnings: list[str] = field(default_factory=list)


@dataclass(frozen=True, kw_only=True)
class LogContext:
    """What the export needs from the original log (None when the log is not at its recorded path)."""

    path: Path
    start_s: float
    end_s: float
    ground_truth: Trajectory | None
    wheel_t0_s: float | None  # first wheel-speed stamp: the time origin of a control replay
    odometry: Trajectory | None = None  # the log's wheel odometry (odom -> base_link), to place its frame


def load_runs(run_dirs: list[Path]) -> list[tuple[Path, RunResult]]:
    """Result directories (or folders of them) of one log, in the order info, slam, control."""
    from mrnc_eval.commands.report import KIND_ORDER, result_dirs_of

    runs = sorted(((d, read_result(d)) for d in result_dirs_of(run_dirs)), key=lambda r: KIND_ORDER.get(r[1].kind, 9))
    logs = sorted({str(Path(r.log_path).resolve()) for _, r in runs if r.log_path != "paper-scenario"})
    if len(logs) > 1:
        raise InputError(run_dirs[0], f"results of different logs ({', '.join(logs)}); one log per export")
    return runs


def _run_config(run_dir: Path) -> Config:
    path = run_dir / CONFIG_FILE_NAME
    return load_config(path) if path.is_file() else load_config()


def read_log_context(log_path: Path, cfg: Config) -> LogContext:
    from mrnc_eval.io import open_log
    from mrnc_eval.io.ground_truth import ground_truth_of

    with open_log(log_path, cfg.io) as lg:
        start, end = lg.start_s, lg.end_s
        gt = ground_truth_of(lg, log_path)
        wheel = lg.wheel_speeds(wheel_radius_m=cfg.robot.wheel_radius_m) if lg.has_role("wheel_speeds") else None
        odom = lg.wheel_odometry() if lg.has_role("wheel_odom") else None
    return LogContext(path=log_path, start_s=start, end_s=end, ground_truth=gt,
                      wheel_t0_s=float(wheel.stamps[0]) if wheel is not None and wheel.stamps.size else None,
                      odometry=odom)


def _slam_files(run_dir: Path) -> topics.SlamFiles:
    from mrnc_eval.io.trajectory_files import read_tum

    def tum(name: str) -> Trajectory | None:
        return read_tum(run_dir / name) if (run_dir / name).is_file() else None

    trajectory = tum("trajectory.tum")
    if trajectory is None or len(trajectory) == 0:
        raise InputError(run_dir, "SLAM result without trajectory.tum: nothing to export")
    return topics.SlamFiles(trajectory, tum("trajectory_online.tum"), tum("keyframes.tum"), _read_map(run_dir))


def _read_map(run_dir: Path) -> np.ndarray | None:
    """The SLAM map's points from map.ply, read without open3d (export is in the base install)."""
    from mrnc_eval.io.ply import read_ply_xyz

    if (run_dir / "map.ply").is_file():
        return read_ply_xyz(run_dir / "map.ply")
    return None


def _control_t0(result: RunResult, ctx: LogContext | None, summary: ExportSummary) -> float:
    """Control series are in seconds since the run's first sample: a replay starts at the first
    wheel-speed stamp (as commands.control.replay uses it), a simulation at the log start."""
    if control_keys.T0_STAMP_S in result.extra:
        return float(result.extra[control_keys.T0_STAMP_S])
    if ctx is not None:
        if result.extra.get(control_keys.MODE) == "replay" and ctx.wheel_t0_s is not None:
            return ctx.wheel_t0_s
        return ctx.start_s
    summary.warnings.append(f"{result.log_id}: control result without its log: time starts at 0")
    return 0.0


BODY_FRAME = "base_link"  # the SLAM's body frame (its trajectories are map -> base_link)


def _fixed_frame(ctx: LogContext | None) -> str:
    """The viewer's fixed frame: the one the ground truth's source declares (the log's `map` in
    recorded and simulated logs); "map" when the ground truth is a file without frames."""
    gt = ctx.ground_truth if ctx is not None else None
    return gt.frame_id if gt is not None and gt.frame_id else "map"


def _write_slam_frames(out: JsonMcap, files: topics.SlamFiles, ctx: LogContext | None, *, fixed: str,
                       frame: str, body: str, summary: ExportSummary, max_diff_s: float) -> None:
    """fixed -> frame (the 4-DoF alignment to the ground truth, identity without one, at the log's
    start so every later lookup finds it), frame -> body (the SLAM pose at each stamp) and, for the
    first method, frame -> odom (REP 105: where the wheel odometry's origin sits)."""
    from mrnc_eval.evaluation.ape import ape

    t0 = float(files.trajectory.stamps[0])
    start_ns = stamp_ns(min(t0, ctx.start_s) if ctx is not None else t0)
    transform = np.eye(4)
    if ctx is not None and ctx.ground_truth is not None:
        # 4-DoF (yaw + translation): both frames are gravity-aligned (IMU, ground truth), and on a
        # near-planar drive a full SE(3) fit tilts the estimate's frame (16 deg on the 6 s test circle,
        # for 0.7 mm less RMSE), which would tilt every cloud drawn through it
        try:
            transform = ape(ctx.ground_truth, files.trajectory, align="yaw", max_diff=max_diff_s).transform
        except EvaluationError as err:
            summary.warnings.append(f"no {fixed} -> {frame} alignment ({err}): identity")
    else:
        summary.warnings.append(f"no ground truth: {frame} drawn in {fixed} without alignment (identity)")
    topics.write_alignment(out, start_ns, transform, parent=fixed, child=frame)
    topics.write_body_transforms(out, files.trajectory, parent=frame, child=body)
    odom = ctx.odometry if ctx is not None else None
    if body == BODY_FRAME and odom is not None and odom.frame_id and odom.frame_id not in (fixed, frame, body):
        odom_in_estimate = topics.odometry_frame(files.trajectory, odom)
        if odom_in_estimate is None:
            summary.warnings.append(f"{odom.frame_id}: no odometry pose near the SLAM poses; frame not placed")
        else:
            topics.write_body_transforms(out, odom_in_estimate, parent=frame, child=odom.frame_id)


def _write_all(out: JsonMcap, runs: list[tuple[Path, RunResult]], ctx: LogContext | None,
               summary: ExportSummary) -> None:
    fixed = _fixed_frame(ctx)
    body_taken = False
    for run_dir, result in runs:
        if result.kind == "slam":
            files = _slam_files(run_dir)
            method = str(result.extra.get(slam_keys.METHOD, "lio"))
            frame = f"{method}/map"
            body = f"{method}/{BODY_FRAME}" if body_taken else BODY_FRAME  # one parent per frame
            body_taken = True
            summary.map_points += topics.write_slam(out, result, files, frame=frame)
            _write_slam_frames(out, files, ctx, fixed=fixed, frame=frame, body=body, summary=summary,
                               max_diff_s=_run_config(run_dir).evaluation.gt_max_diff_s)
            topics.write_events(out, result, float(files.trajectory.stamps[0]), f"slam/{method}")
        elif result.kind == "control":
            cfg = _run_config(run_dir).control
            t0 = _control_t0(result, ctx, summary)
            topics.write_control(out, result, t0, u_max_rpm=cfg.actuator.u_max_rpm,
                                 saturation_tol_rpm=cfg.metrics.saturation_tolerance_rpm, frame=fixed)
            topics.write_events(out, result, t0, "control")
        elif result.kind == "info" and ctx is not None:
            topics.write_events(out, result, ctx.start_s, "info")
    if ctx is not None and ctx.ground_truth is not None:
        topics.write_ground_truth(out, ctx.ground_truth, fixed)


def run_inputs(runs: list[tuple[Path, RunResult]]) -> list[Path]:
    """What the runs read and hold: each log (file or ROS 2 bag folder), the ground truth beside
    it, and the result folders themselves; an export never replaces any of them."""
    from mrnc_eval.io.ground_truth import gt_tum_path

    found: list[Path] = []
    for run_dir, r in runs:
        found.append(run_dir)
        if r.log_path and r.log_path != "paper-scenario":
            found += [Path(r.log_path), gt_tum_path(Path(r.log_path))]
    return found


def export_mcap(run_dirs: list[Path], out_path: Path, *, with_log: bool = False, force: bool = False
                ) -> ExportSummary:
    """Write the MCAP; see the module docstring."""
    if out_path.suffix.lower() != ".mcap":
        raise UsageError(f"--mcap {out_path}: the file name must end in .mcap")
    runs = load_runs(run_dirs)
    claim_output(out_path, force=force, inputs=run_inputs(runs))
    summary = ExportSummary(path=out_path)
    log_path = next((Path(r.log_path) for _, r in runs if r.log_path != "paper-scenario"), None)
    ctx = None
    if log_path is not None and log_path.exists():
        ctx = read_log_context(log_path, _run_config(runs[0][0]))
    elif with_log:
        raise InputError(log_path or run_dirs[0], "--with-log: the original log is not at its recorded path")
    else:
        summary.warnings.append(f"log {log_path} not found: no ground truth, control time from 0")
    with output_file(out_path, force=force, inputs=run_inputs(runs)) as tmp, tmp.open("wb") as fh:
        out = JsonMcap(fh)
        _write_all(out, runs, ctx, summary)
        summary.counts.update(out.counts)
        if with_log and ctx is not None:
            from mrnc_eval.export.log_copy import copy_log

            summary.counts.update(copy_log(out.writer, ctx.path, topics.ROOT))
        out.finish()
    summary.size_bytes = out_path.stat().st_size
    return summary


def main(run_dirs: list[Path], *, mcap: Path, with_log: bool, force: bool) -> None:
    summary = export_mcap(run_dirs, mcap, with_log=with_log, force=force)
    for w in summary.warnings:
        sys.stderr.write(f"warning: {printable(w)}\n")
    total = sum(summary.counts.values())
    sys.stdout.write(f"{summary.path}: {summary.size_bytes / 1e6:.2f} MB, {total} messages on "
                     f"{len(summary.counts)} topics, map {summary.map_points} points\n")
    for topic, n in sorted(summary.counts.items()):
        sys.stdout.write(f"  {printable(topic)}: {n}\n")  # a log's topic names
