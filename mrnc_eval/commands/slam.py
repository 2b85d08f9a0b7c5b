"""`mrnc-eval slam`: replay the SLAM (or the kiss-icp peer) on logs, evaluate, write results."""

from __future__ import annotations

import datetime as dt
import logging
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mrnc_eval.commands.progress import progress_bar
from mrnc_eval.config import Config, config_hash, dump_config, replace_path
from mrnc_eval.data import Trajectory
from mrnc_eval.errors import EvaluationError, InputError, UsageError
from mrnc_eval.evaluation.comparison import Cell, judge, table_one
from mrnc_eval.io.prefetch import Prefetched
from mrnc_eval.results import Event, Metric, RunResult, json_safe, log_id_for, write_result
from mrnc_eval.slam.replay import STAGES, SlamOutput

log = logging.getLogger(__name__)
METHODS = ("lio", "kiss-icp")


def _ground_truth(lg, log_path: Path) -> Trajectory | None:
    from mrnc_eval.io.ground_truth import gt_tum_path
    from mrnc_eval.io.trajectory_files import read_tum

    if lg.has_role("ground_truth"):
        return lg.ground_truth()
    beside = gt_tum_path(log_path)
    return read_tum(beside) if beside.exists() else None


def _kiss_icp(sweeps, cfg: Config) -> SlamOutput:
    """The peer on the same Sweep arrays: KISS-ICP's own deskew and adaptive threshold."""
    import time

    try:
        from kiss_icp.config import load_config
        from kiss_icp.kiss_icp import KissICP
    except ImportError as err:
        raise UsageError("--method kiss-icp needs the kiss-icp extra: pip install 'mrnc-eval[kiss-icp]'") from err
    kcfg = load_config(None)
    kcfg.data.max_range = 100.0
    kcfg.data.min_range = cfg.slam.features.min_range_m
    kcfg.data.deskew = True
    icp = KissICP(kcfg)
    stamps, poses = [], []
    t_match, t_read = [], []
    wall0 = t_prev = time.perf_counter()
    n = 0
    for s in sweeps:
        n += 1
        t0 = time.perf_counter()
        t_read.append((t0 - t_prev) * 1e3)
        if s.point_time is None:
            ts = np.zeros(len(s))
        else:  # kiss-icp deskews with per-point time normalised to [0, 1]
            ts = s.point_time.astype(np.float64) / max(float(s.point_time.max()), 1e-9)
        icp.register_frame(s.points.astype(np.float64), ts)
        t_match.append((time.perf_counter() - t0) * 1e3)
        stamps.append(s.stamp)
        poses.append(np.asarray(icp.last_pose))
        t_prev = time.perf_counter()
    timing = {st: [0.0] * len(t_match) for st in STAGES}
    timing["matching"], timing["read"] = t_match, t_read
    return SlamOutput(np.asarray(stamps), np.asarray(poses), np.asarray(stamps), np.asarray(poses), np.zeros((0, 3)),
                      timing, [], [], n, time.perf_counter() - wall0)


def _to_base(stamps: np.ndarray, sensor_poses: np.ndarray, base_to_sensor: np.ndarray, name: str) -> Trajectory:
    """LiDAR poses in the map as base_link poses (through /tf_static)."""
    base = sensor_poses.reshape(-1, 4, 4) @ np.linalg.inv(base_to_sensor)
    return Trajectory(stamps, base[:, :3, 3], Rotation.from_matrix(base[:, :3, :3]).as_quat(), name=name,
                      frame_id="map", child_frame_id="base_link")


def _end_drift(gt: Trajectory, est: Trajectory) -> float:
    """Distance (m) between the estimated and true last position once the first poses coincide."""
    from mrnc_eval.evaluation.ape import ape

    return float(ape(gt, est, align="origin", max_diff=0.02).errors[-1])


def run_log(log_path: Path, cfg: Config, out_dir: Path, *, method: str = "lio", progress: bool = False,
            log_id: str | None = None) -> RunResult:
    """Replay `method` on one log into `out_dir`; `log_id` names the log in results (default:
    from its file name; the nightly job passes its own, unique within the night)."""
    from mrnc_eval.evaluation.ape import ape
    from mrnc_eval.io import open_log
    from mrnc_eval.io.trajectory_files import write_tum
    from mrnc_eval.slam.replay import run_slam

    if method not in METHODS:
        raise UsageError(f"--method {method!r}: choose from {', '.join(METHODS)}")
    import json
    import time

    wall_start = time.perf_counter()
    result = RunResult(kind="slam", log_path=str(log_path), log_id=log_id or log_id_for(log_path),
                       config_hash=config_hash(cfg))
    with open_log(log_path, cfg.io) as lg:
        if not lg.has_role("lidar"):
            raise InputError(log_path, "no LiDAR topic (sensor_msgs/PointCloud2): nothing to run SLAM on")
        duration = lg.duration_s  # the overview pass first: it keeps IMU, GNSS, TF and ground truth in memory
        lidar_frame = cfg.slam.sensor.lidar_frame
        statics = lg.static_transforms()
        frames = {c for _, c in statics} | {p for p, _ in statics}
        base_to_sensor = lg.transform("base_link", lidar_frame) if {"base_link", lidar_frame} <= frames else np.eye(4)
        imu = lg.imu() if lg.has_role("imu") else None
        sensor_to_imu = np.eye(4)
        if imu is not None and imu.frame_id and imu.frame_id in frames and lidar_frame in frames:
            sensor_to_imu = lg.transform(lidar_frame, imu.frame_id)
        gnss = lg.gnss() if lg.has_role("gnss") else None
        gt = _ground_truth(lg, log_path)
        has_antenna = "gnss" in frames and "base_link" in frames
        antenna = lg.transform("base_link", "gnss")[:3, 3] if has_antenna else np.zeros(3)
        antenna_in_sensor = (np.linalg.inv(base_to_sensor) @ np.r_[antenna, 1.0])[:3]
        total = next(t.count for t in lg.topics if t.topic == lg.roles["lidar"])
        with progress_bar(total, progress) as b:
            task = b.add_task("SLAM sweeps", total=total) if b else None
            tick = (lambda n: b.update(task, completed=n)) if b else None
            # both methods read the same way: decoding runs ahead in a thread ("read" = time still waited)
            stream = lg.sweeps(min_interval_s=cfg.slam.mapping_interval_s) if method == "lio" else lg.sweeps()
            with Prefetched(stream, depth=4) as sweeps:
                if method == "lio":
                    out = run_slam(sweeps, imu, cfg.slam, sensor_to_imu=sensor_to_imu, gnss=gnss,
                                   antenna_in_sensor=antenna_in_sensor, progress=tick)
                else:
                    out = _kiss_icp(sweeps, cfg)
    if out.stamps.size < 2:
        raise EvaluationError(f"{log_path}: SLAM produced {out.stamps.size} pose(s)")
    est = _to_base(out.stamps, out.poses, base_to_sensor, method)
    keyframes = _to_base(out.kf_stamps, out.kf_poses, base_to_sensor, f"{method} keyframes")
    result.warnings += out.warnings
    if imu is None:
        result.warnings.append("log has no IMU topic")
    t_start = float(out.stamps[0])
    for e in out.events:
        result.events.append(Event(e.t - t_start, e.kind, e.message, e.data))
    # ---- metrics
    rtf = duration / out.wall_s if out.wall_s > 0 else float("inf")
    total_s = time.perf_counter() - wall_start
    result.metrics += [Metric("rtf", rtf, "", "slam", lower_is_better=False,
                              note="log duration / wall time of the SLAM over the sweep stream (decoding included)"),
                       Metric("rtf_end_to_end", duration / total_s, "", "slam", lower_is_better=False,
                              note="log duration / wall time including reading IMU, GNSS and ground truth"),
                       Metric("sweeps_processed", int(out.stamps.size), "", "slam"),
                       Metric("keyframes", int(out.kf_stamps.size), "", "slam"),
                       Metric("loop_closures", sum(e.kind == "loop_closure" for e in out.events), "", "slam"),
                       Metric("degeneracy_events", sum(e.kind == "degeneracy" for e in out.events), "", "slam")]
    timing = {}
    first_ms = float(sum(v[0] for v in out.timing_ms.values() if v))
    for stage in STAGES:  # the first sweep is left out: on a fresh install it includes numba's one-off compilation
        vals = np.asarray(out.timing_ms[stage][1:] or out.timing_ms[stage] or [0.0])
        timing[stage] = {"mean": float(vals.mean()), "p95": float(np.percentile(vals, 95)), "max": float(vals.max())}
        result.metrics.append(Metric(f"ms_per_sweep_{stage}", timing[stage]["mean"], "ms", "slam/timing"))
    result.extra.update({"method": method, "timing_ms": timing, "wall_s": out.wall_s, "log_duration_s": duration,
                         "sweeps_decoded": out.n_sweeps, "wall_total_s": total_s, "first_sweep_ms": first_ms,
                         "imu_bias": None if out.imu_bias is None else out.imu_bias.tolist(),
                         "frames": {"trajectory.tum": "map -> base_link (LiDAR poses through /tf_static)",
                                    "stamps": "sweep header stamps (sweep start)"}})
    result.series["est_t"] = est.stamps - t_start
    result.series["est_xyz"] = est.positions
    result.series["kf_xyz"] = keyframes.positions
    if gt is not None:
        try:
            r = ape(gt, est, align="se3", max_diff=0.02)
            result.metrics += [Metric("ape_rmse_m", r.stats["rmse"], "m", "slam/ape"),
                               Metric("ape_mean_m", r.stats["mean"], "m", "slam/ape"),
                               Metric("ape_max_m", r.stats["max"], "m", "slam/ape"),
                               Metric("ape_n", r.n, "", "slam/ape"), Metric("ape_span_s", r.span_s, "s", "slam/ape"),
                               Metric("end_drift_m", _end_drift(gt, est), "m", "slam/ape",
                                      note="position error of the last pose with the first pose aligned to the "
                                           "ground truth: the drift accumulated over the log")]
            result.series["ape_t"] = r.stamps - t_start
            result.series["ape_err_m"] = r.errors
            result.series["ref_xyz"] = r.ref_poses[:, :3, 3]
            result.series["est_aligned_xyz"] = r.est_poses[:, :3, 3]
            cell = judge(r.stats["rmse"], r.n, r.span_s, r.ref_span_s, min_matches=cfg.evaluation.failed_min_matches,
                         min_span_fraction=cfg.evaluation.failed_min_span_fraction)
        except EvaluationError as err:
            result.warnings.append(f"APE against ground truth failed: {err}")
            cell = Cell(None, str(err))
        result.tables.append(table_one({(result.log_id, method): cell}, [result.log_id], [method],
                                       title="APE RMSE (SE(3) aligned)"))
    else:
        result.warnings.append("no ground truth (topic or <log>.gt.tum): APE not computed")
    if gnss is not None and gnss.stamps.size > 3:
        try:
            ref = Trajectory(gnss.stamps, gnss.enu, np.tile([0, 0, 0, 1.0], (gnss.stamps.size, 1)), name="gnss")
            shifted = Trajectory(est.stamps, est.positions + Rotation.from_quat(est.quat_xyzw).apply(antenna),
                                 est.quat_xyzw, name=method)
            rg = ape(ref, shifted, align="yaw", relation="point", max_diff=0.1, plane="xy")
            result.metrics.append(Metric("ape_gnss_rmse_m", rg.stats["rmse"], "m", "slam/ape",
                                         note="2-D, yaw + translation alignment, against GNSS in ENU"))
        except EvaluationError as err:
            result.warnings.append(f"APE against GNSS failed: {err}")
    # ---- files
    tmp = Path(tempfile.mkdtemp(prefix=".slam-files-"))
    write_tum(tmp / "trajectory.tum", est)
    write_tum(tmp / "keyframes.tum", keyframes)
    files = {"trajectory.tum": tmp / "trajectory.tum", "keyframes.tum": tmp / "keyframes.tum"}
    if out.map_points.size:
        import open3d as o3d

        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(out.map_points))
        for name in ("map.ply", "map.pcd"):
            o3d.io.write_point_cloud(str(tmp / name), pc)
            files[name] = tmp / name
    metrics = {m.name: {"value": m.value, "unit": m.unit} for m in result.metrics}
    (tmp / "metrics.json").write_text(json.dumps(json_safe(metrics), indent=2), encoding="utf-8")
    files["metrics.json"] = tmp / "metrics.json"
    try:
        write_result(result, out_dir, dump_config(cfg), files)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return result


def main(logs: list[Path], cfg: Config, *, method: str, out: Path, no_loop: bool, no_gps: bool, json_out: bool) -> None:
    from mrnc_eval.errors import SomeInputsFailed
    from mrnc_eval.reports.tables import render_table

    if no_loop:
        cfg = replace_path(cfg, "slam.use_loop_closure", False)
    if no_gps:
        cfg = replace_path(cfg, "slam.use_gps", False)
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    results, failed, cells = [], [], {}
    for path in logs:
        run_dir = out / f"{log_id_for(path)}-slam-{method}-{stamp}"
        try:
            r = run_log(path, cfg, run_dir, method=method, progress=True)
        except InputError as err:
            if len(logs) == 1:
                raise
            failed.append((path, str(err)))
            cells[(log_id_for(path), method)] = Cell(None, str(err))
            continue
        results.append((run_dir, r))
        m = r.metric("ape_rmse_m")
        cells[(r.log_id, method)] = Cell(m.value if m else None, "" if m else "no ground truth")
    if json_out:
        from mrnc_eval.commands.output import emit_json

        emit_json([{"log": r.log_path, "run_dir": str(d), **{m.name: m.value for m in r.metrics}}
                    for d, r in results])
    else:
        for d, r in results:
            vals = {m.name: m.value for m in r.metrics}
            ape = f"{vals['ape_rmse_m']:.4f} m" if "ape_rmse_m" in vals else "n/a (no ground truth)"
            sys.stdout.write(f"{r.log_id}: APE RMSE {ape}, RTF {vals['rtf']:.2f}, "
                             f"{vals['keyframes']} keyframes, {vals['loop_closures']} loop closures -> {d}\n")
        if len(logs) > 1:
            sys.stdout.write(render_table(table_one(cells, [log_id_for(p) for p in logs], [method]), "markdown"))
    if failed:
        raise SomeInputsFailed("; ".join(f"{p}: {e}" for p, e in failed))
