"""The SLAM replay, sweep by sweep, in LIO-SAM's order:
guess from the IMU -> deskew -> features -> scan-to-map -> keyframe, graph, GNSS, loop closure."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from mrnc_eval.data import GnssSeries, ImuSeries, Sweep
from mrnc_eval.slam import se3
from mrnc_eval.slam.config import SlamConfig
from mrnc_eval.slam.deskew import deskew
from mrnc_eval.slam.features import Features, extract_features, voxel_downsample
from mrnc_eval.slam.graph import KeyframeGraph, loop_candidate, register_loop
from mrnc_eval.slam.imu import Preintegrator, imu_track, initial_attitude
from mrnc_eval.slam.scan_to_map import LocalMap, match

STAGES = ("deskew", "features", "matching", "graph", "loop")


@dataclass
class SlamEvent:
    t: float
    kind: str  # "degeneracy", "loop_closure", "warning", "gps"
    message: str
    data: dict = field(default_factory=dict)


@dataclass
class SlamOutput:
    stamps: np.ndarray  # processed sweeps, s
    poses: np.ndarray  # (N, 4, 4) sensor poses in the map frame, loop-corrected through their keyframe
    kf_stamps: np.ndarray
    kf_poses: np.ndarray
    map_points: np.ndarray
    timing_ms: dict[str, list[float]]
    events: list[SlamEvent]
    warnings: list[str]
    n_sweeps: int
    wall_s: float


def run_slam(sweeps: Iterable[Sweep], imu: ImuSeries | None, cfg: SlamConfig, *, sensor_to_imu: np.ndarray,
             gnss: GnssSeries | None = None, gnss_to_sensor_offset: np.ndarray | None = None,
             progress: Callable[[int], None] | None = None) -> SlamOutput:
    wall0 = time.perf_counter()
    warnings: list[str] = []
    events: list[SlamEvent] = []
    timing: dict[str, list[float]] = {s: [] for s in STAGES}
    rot_si = sensor_to_imu[:3, :3]
    track = pre = None
    if imu is not None and imu.stamps.size > 2:
        bias = None
        if cfg.gyro_bias_init_s > 0:
            sel = imu.stamps <= imu.stamps[0] + cfg.gyro_bias_init_s
            bias = imu.gyro[sel].mean(axis=0)
        track = imu_track(imu, rot_si, bias)
        pre = Preintegrator(track)
        attitude = initial_attitude(imu, rot_si)
    else:
        warnings.append("no IMU: no deskew rotation, no attitude initialisation, constant-velocity guess only")
        attitude = Rotation.identity()
    graph = KeyframeGraph(cfg.graph)
    kf_features: list[Features] = []
    map_cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    local_map: LocalMap | None = None
    stamps, rel_to_kf, ref_kf = [], [], []
    prev_pose = prev_prev_pose = None
    prev_t = prev_prev_t = None
    last_processed = -np.inf
    warned_no_time = warned_no_cover = False
    n_sweeps = 0
    use_loop = cfg.use_loop_closure and cfg.loop.enabled
    use_gps = cfg.use_gps and cfg.gps.enabled and gnss is not None and gnss.stamps.size > 0

    for sweep in sweeps:
        n_sweeps += 1
        if progress is not None:
            progress(n_sweeps)
        if sweep.stamp - last_processed < cfg.mapping_interval_s or len(sweep) == 0:
            continue
        last_processed = sweep.stamp
        # ---- motion prior
        velocity_world = None
        if prev_pose is not None and prev_prev_pose is not None and prev_t > prev_prev_t:
            velocity_world = (prev_pose[:3, 3] - prev_prev_pose[:3, 3]) / (prev_t - prev_prev_t)
        # ---- deskew
        t0 = time.perf_counter()
        pts = sweep.points
        if sweep.point_time is None:
            if not warned_no_time:
                warnings.append("sweeps have no per-point time: processed without deskew")
                warned_no_time = True
            pts = pts.astype(np.float64)
        else:
            duration = float(sweep.point_time.max())
            covered = track is not None and track.covers(sweep.stamp, sweep.stamp + duration)
            if track is not None and not covered and not warned_no_cover:
                warnings.append(f"IMU does not cover sweep at {sweep.stamp:.3f}: rotation deskew clamped to the IMU span")
                warned_no_cover = True
            v_sensor = None
            if cfg.deskew_translation and velocity_world is not None and prev_pose is not None:
                v_sensor = prev_pose[:3, :3].T @ velocity_world
            pts = deskew(pts, sweep.point_time, sweep.stamp, track, v_sensor)
        timing["deskew"].append((time.perf_counter() - t0) * 1e3)
        # ---- features
        t0 = time.perf_counter()
        ring = sweep.ring if sweep.ring is not None else np.zeros(len(sweep), np.uint16)
        column = sweep.column if sweep.column is not None else np.arange(len(sweep), dtype=np.uint32)
        feats = extract_features(pts, ring, column, cfg.features)
        timing["features"].append((time.perf_counter() - t0) * 1e3)
        # ---- guess and scan-to-map
        t0 = time.perf_counter()
        if prev_pose is None:
            guess = se3.make(attitude.as_matrix(), np.zeros(3))
        elif pre is not None and velocity_world is not None and track.covers(prev_t, sweep.stamp):
            guess, _ = pre.predict(prev_pose, velocity_world, prev_t, sweep.stamp)
        elif track is not None and track.covers(prev_t, sweep.stamp):
            dR = track.rotation_between(prev_t, np.array([sweep.stamp]))[0].as_matrix()
            step = (velocity_world if velocity_world is not None else np.zeros(3)) * (sweep.stamp - prev_t)
            guess = se3.make(prev_pose[:3, :3] @ dR, prev_pose[:3, 3] + step)
        else:
            step = (velocity_world if velocity_world is not None else np.zeros(3)) * (sweep.stamp - prev_t)
            guess = se3.make(prev_pose[:3, :3], prev_pose[:3, 3] + step)
        if local_map is None:
            pose = guess
        else:
            res = match(feats.edges, feats.surfs, local_map, guess, cfg.matching)
            pose = res.pose
            if res.degenerate:
                events.append(SlamEvent(sweep.stamp, "degeneracy",
                                        f"scan-to-map degenerate (min eigenvalue {res.min_eigenvalue:.1f} < "
                                        f"{cfg.matching.degeneracy_eigen_threshold:g})",
                                        {"min_eigenvalue": res.min_eigenvalue}))
            if not res.optimised:
                events.append(SlamEvent(sweep.stamp, "warning",
                                        f"too few features ({res.n_edges} edges, {res.n_surfs} planes): kept the guess"))
        timing["matching"].append((time.perf_counter() - t0) * 1e3)
        # ---- keyframe and graph
        t0 = time.perf_counter()
        new_kf = not graph.poses
        if graph.poses:
            d = se3.inv(graph.poses[-1]) @ pose
            new_kf = (np.linalg.norm(d[:3, 3]) >= cfg.graph.keyframe_dist_m
                      or np.any(np.abs(se3.rpy(d)) >= cfg.graph.keyframe_angle_rad))
        loop_ms = 0.0
        if new_kf:
            pose = graph.add_keyframe(pose, sweep.stamp)
            kf_features.append(feats)
            k = len(graph.poses) - 1
            if use_gps:
                _maybe_gps(graph, gnss, gnss_to_sensor_offset, sweep.stamp, cfg, events)
            if use_loop and k % max(1, cfg.loop.every_n_keyframes) == 0:
                tl = time.perf_counter()
                if _try_loop(graph, kf_features, cfg, events, sweep.stamp):
                    map_cache.clear()
                loop_ms = (time.perf_counter() - tl) * 1e3
            pose = graph.poses[-1]
            local_map = _local_map(graph, kf_features, map_cache, cfg)
        timing["graph"].append((time.perf_counter() - t0) * 1e3 - loop_ms)
        timing["loop"].append(loop_ms)
        k_ref = len(graph.poses) - 1
        stamps.append(sweep.stamp)
        ref_kf.append(k_ref)
        rel_to_kf.append(se3.inv(graph.poses[k_ref]) @ pose)
        prev_prev_pose, prev_prev_t = prev_pose, prev_t
        prev_pose, prev_t = pose, sweep.stamp

    kf_poses = np.array(graph.poses) if graph.poses else np.zeros((0, 4, 4))
    poses = np.array([kf_poses[k] @ r for k, r in zip(ref_kf, rel_to_kf)]) if stamps else np.zeros((0, 4, 4))
    map_points = np.zeros((0, 3))
    if kf_features:
        map_points = voxel_downsample(np.vstack([se3.apply(kf_poses[i], np.r_[f.edges, f.surfs])
                                                 for i, f in enumerate(kf_features)]), cfg.matching.surf_leaf_m)
    return SlamOutput(np.asarray(stamps), poses, np.asarray(graph.stamps), kf_poses, map_points, timing, events,
                      warnings, n_sweeps, time.perf_counter() - wall0)


def _local_map(graph: KeyframeGraph, feats: list[Features], cache, cfg: SlamConfig) -> LocalMap:
    pos = np.array([p[:3, 3] for p in graph.poses])
    t = np.asarray(graph.stamps)
    near = np.linalg.norm(pos - pos[-1], axis=1) <= cfg.matching.map_radius_m
    recent = t >= t[-1] - cfg.matching.map_recent_s
    edges, surfs = [], []
    for i in np.flatnonzero(near | recent):
        if i not in cache:
            cache[i] = (se3.apply(graph.poses[i], feats[i].edges), se3.apply(graph.poses[i], feats[i].surfs))
        edges.append(cache[i][0])
        surfs.append(cache[i][1])
    return LocalMap.build(voxel_downsample(np.vstack(edges), cfg.matching.corner_leaf_m),
                          voxel_downsample(np.vstack(surfs), cfg.matching.surf_leaf_m))


def _try_loop(graph: KeyframeGraph, feats: list[Features], cfg: SlamConfig, events: list[SlamEvent],
              stamp: float) -> bool:
    prev = loop_candidate(graph, cfg.loop)
    if prev is None:
        return False
    cur = len(graph.poses) - 1
    src = se3.apply(graph.poses[cur], np.r_[feats[cur].edges, feats[cur].surfs])
    lo, hi = max(0, prev - cfg.loop.neighbours), min(cur, prev + cfg.loop.neighbours + 1)
    tgt = voxel_downsample(np.vstack([se3.apply(graph.poses[i], np.r_[feats[i].edges, feats[i].surfs])
                                      for i in range(lo, hi)]), 0.4)
    if len(src) < 300 or len(tgt) < 1000:
        return False
    T, fitness, ok = register_loop(src, tgt, np.eye(4), cfg.loop)
    if not ok or fitness > cfg.loop.fitness_threshold_m2:
        return False
    corrected = T @ graph.poses[cur]
    relative = se3.inv(graph.poses[prev]) @ corrected
    before = graph.poses[cur][:3, 3].copy()
    graph.add_loop(cur, prev, relative, fitness)
    events.append(SlamEvent(stamp, "loop_closure", f"keyframe {cur} -> {prev}, fitness {fitness:.3f} m^2, "
                            f"moved {np.linalg.norm(graph.poses[cur][:3, 3] - before):.3f} m",
                            {"current": cur, "previous": prev, "fitness": fitness}))
    return True


def _maybe_gps(graph: KeyframeGraph, gnss: GnssSeries, offset: np.ndarray | None, stamp: float, cfg: SlamConfig,
               events: list[SlamEvent]) -> None:
    g = cfg.gps
    if len(graph.poses) < 2 or np.linalg.norm(graph.poses[-1][:3, 3] - graph.poses[0][:3, 3]) < 5.0:
        return
    if graph.xy_variance() < g.pose_cov_threshold_m2:
        return  # LIO-SAM adds GNSS only when the pose has become uncertain
    i = int(np.argmin(np.abs(gnss.stamps - stamp)))
    if abs(gnss.stamps[i] - stamp) > g.max_time_diff_s:
        return
    var = np.diag(gnss.covariance[i])
    if var[0] > g.gps_cov_threshold_m2 or var[1] > g.gps_cov_threshold_m2:
        return
    enu = gnss.enu[i] - (offset if offset is not None else 0.0)
    if graph.last_gps_xy is not None and np.linalg.norm(enu[:2] - graph.last_gps_xy) < g.min_spacing_m:
        return
    graph.add_gps(len(graph.poses) - 1, enu, var)
    events.append(SlamEvent(stamp, "gps", f"GNSS factor at keyframe {len(graph.poses) - 1}"))
