"""The SLAM replay, sweep by sweep, in LIO-SAM's order:
skip (mappingProcessInterval) -> range image -> deskew -> features -> guess from graph #2 ->
scan-to-map -> graph #2 correction -> keyframe: graph #1, GNSS, loop closure, local map."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from mrnc_eval.data import GnssSeries, ImuSeries, Sweep
from mrnc_eval.errors import ProcessingError
from mrnc_eval.slam import se3
from mrnc_eval.slam.config import SlamConfig
from mrnc_eval.slam.deskew import deskew
from mrnc_eval.slam.features import Features, extract_features, voxel_downsample
from mrnc_eval.slam.gnss import GnssAligner
from mrnc_eval.slam.graph import KeyframeGraph, loop_candidate, register_loop
from mrnc_eval.slam.imu import ImuOdometry, ImuTrack, clean_imu, imu_track, initial_attitude, lidar_to_imu
from mrnc_eval.slam.range_image import project
from mrnc_eval.slam.scan_to_map import LocalMap, MatchResult, match

STAGES = ("read", "deskew", "features", "matching", "graph", "loop")  # read: waiting for the sweep iterator (decode)


@dataclass
class SlamEvent:
    t: float  # log time, s
    kind: str  # "degeneracy", "loop_closure", "warning", "gps"
    message: str
    data: dict = field(default_factory=dict)


@dataclass
class SlamOutput:
    stamps: np.ndarray  # processed sweeps, s
    poses: np.ndarray  # (N, 4, 4) LiDAR poses in the map frame, loop-corrected through their keyframe
    kf_stamps: np.ndarray
    kf_poses: np.ndarray
    map_points: np.ndarray
    timing_ms: dict[str, list[float]]
    events: list[SlamEvent]
    warnings: list[str]
    n_sweeps: int
    wall_s: float
    imu_bias: np.ndarray | None = None  # final [acc (3), gyro (3)] bias estimate of graph #2, LiDAR axes
    degenerate: np.ndarray | None = None  # (N,) bool per processed sweep


@dataclass
class _State:
    """What the replay carries from one mapped sweep to the next."""

    pose: np.ndarray | None = None
    t: float | None = None
    velocity: np.ndarray | None = None  # world frame, m/s
    last_mapped: float = -np.inf
    last_loop_t: float = -np.inf
    warned: set = field(default_factory=set)


def run_slam(sweeps: Iterable[Sweep], imu: ImuSeries | None, cfg: SlamConfig, *,
             sensor_to_imu: np.ndarray | None = None, gnss: GnssSeries | None = None,
             antenna_in_sensor: np.ndarray | None = None,
             progress: Callable[[int], None] | None = None) -> SlamOutput:
    """Replay the SLAM over `sweeps` (LiDAR frame). `sensor_to_imu` is the IMU pose in the LiDAR
    frame from /tf_static (the config's extrinsics override it); `gnss` in ENU enables GNSS factors."""
    wall0 = time.perf_counter()
    warnings: list[str] = []
    events: list[SlamEvent] = []
    timing: dict[str, list[float]] = {s: [] for s in STAGES}
    extr = lidar_to_imu(cfg.imu, sensor_to_imu)
    track, odom, imu = _imu_setup(imu, extr, cfg, warnings)
    graph = KeyframeGraph(cfg.graph)
    aligner = GnssAligner(gnss, cfg.gps, antenna_in_sensor) if (gnss is not None and cfg.use_gps and cfg.gps.enabled
                                                              and gnss.stamps.size > 0) else None
    kf_features: list[Features] = []
    map_cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    local_map: LocalMap | None = None
    stamps, rel_to_kf, ref_kf, degenerate = [], [], [], []
    st = _State()
    n_sweeps = 0
    use_loop = cfg.use_loop_closure and cfg.loop.enabled
    t_read = time.perf_counter()

    for sweep in sweeps:
        n_sweeps += 1
        if progress is not None:
            progress(n_sweeps)
        if sweep.stamp - st.last_mapped < cfg.mapping_interval_s or len(sweep) == 0:
            continue
        st.last_mapped = sweep.stamp
        timing["read"].append((time.perf_counter() - t_read) * 1e3)
        clock = _Clock(timing)
        # ---- range image + deskew
        image = project(sweep, cfg.sensor, cfg.features)
        pts = _deskew(image, sweep, track, st, cfg, warnings, events)
        clock.lap("deskew")
        # ---- features
        feats = extract_features(image, pts, cfg.features)
        clock.lap("features")
        # ---- guess and scan-to-map
        guess = _guess(st, sweep.stamp, track, odom, imu, extr, cfg)
        res: MatchResult | None = None
        pose = guess
        if local_map is not None:
            res = match(feats.edges, feats.surfs, local_map, guess, cfg.matching)
            pose = _imu_attitude_blend(res.pose, imu, extr, sweep.stamp, cfg)
            _report_match(res, sweep.stamp, cfg, events)
        is_degenerate = bool(res is not None and res.degenerate)
        if odom is not None:
            why = odom.add_lidar_pose(pose, sweep.stamp, is_degenerate)
            if why:
                events.append(SlamEvent(sweep.stamp, "warning", why))
        clock.lap("matching")
        # ---- keyframe: graph #1, GNSS, loop closure, local map
        loop_ms = 0.0
        if _is_keyframe(graph, pose, cfg):
            pose = graph.add_keyframe(pose, sweep.stamp)
            kf_features.append(feats)
            if aligner is not None and aligner.maybe_add(graph, sweep.stamp, events):
                map_cache.clear()
            if use_loop and sweep.stamp - st.last_loop_t >= cfg.loop.interval_s:
                st.last_loop_t = sweep.stamp
                tl = time.perf_counter()
                moved = _try_loop(graph, kf_features, cfg, events, sweep.stamp)
                if moved is not None:
                    map_cache.clear()
                    if odom is not None and moved > cfg.imu.restart_after_loop_m:
                        odom.restart()  # the global pose jumped: graph #2 restarts from it
                loop_ms = (time.perf_counter() - tl) * 1e3
            pose = graph.poses[-1]
            local_map = _local_map(graph, kf_features, map_cache, cfg)
        clock.lap("graph", minus_ms=loop_ms)
        timing["loop"].append(loop_ms)
        # ---- bookkeeping
        k_ref = len(graph.poses) - 1
        stamps.append(sweep.stamp)
        ref_kf.append(k_ref)
        rel_to_kf.append(se3.inv(graph.poses[k_ref]) @ pose)
        degenerate.append(is_degenerate)
        if odom is not None:
            st.velocity = odom.velocity.copy()
        elif st.pose is not None and sweep.stamp > st.t:
            st.velocity = (pose[:3, 3] - st.pose[:3, 3]) / (sweep.stamp - st.t)
        st.pose, st.t = pose, sweep.stamp
        t_read = time.perf_counter()

    kf_poses = np.array(graph.poses) if graph.poses else np.zeros((0, 4, 4))
    poses = np.zeros((0, 4, 4))
    if stamps:
        poses = np.array([kf_poses[k] @ r for k, r in zip(ref_kf, rel_to_kf, strict=True)])
    map_points = np.zeros((0, 3))
    if kf_features:
        map_points = voxel_downsample(np.vstack([se3.apply(kf_poses[i], np.r_[f.edges, f.surfs])
                                                 for i, f in enumerate(kf_features)]), cfg.matching.surf_leaf_m)
    return SlamOutput(np.asarray(stamps), poses, np.asarray(graph.stamps), kf_poses, map_points, timing, events,
                      warnings, n_sweeps, time.perf_counter() - wall0,
                      odom.bias_vector if odom is not None else None, np.asarray(degenerate, bool))


class _Clock:
    """Per-stage wall time (ms) of one sweep."""

    def __init__(self, timing: dict[str, list[float]]) -> None:
        self.timing, self.t = timing, time.perf_counter()

    def lap(self, stage: str, minus_ms: float = 0.0) -> None:
        now = time.perf_counter()
        self.timing[stage].append((now - self.t) * 1e3 - minus_ms)
        self.t = now


def _imu_setup(imu: ImuSeries | None, extr: np.ndarray, cfg: SlamConfig, warnings: list[str]):
    if imu is None or imu.stamps.size < 3:
        warnings.append("no IMU: no deskew rotation, no attitude initialisation, constant-velocity guess only")
        return None, None, None
    imu = clean_imu(imu)
    bias = None
    if cfg.gyro_bias_init_s > 0:
        bias = imu.gyro[imu.stamps <= imu.stamps[0] + cfg.gyro_bias_init_s].mean(axis=0)
    track = imu_track(imu, extr[:3, :3], bias)
    odom = ImuOdometry(track, cfg.imu, extr) if cfg.imu.use_preintegration_graph else None
    return track, odom, imu


def _deskew(image, sweep: Sweep, track: ImuTrack | None, st: _State, cfg: SlamConfig, warnings: list[str],
            events: list[SlamEvent]) -> np.ndarray:
    if image.point_time is None:
        _warn_once(st, warnings, events, sweep.stamp, "no_time", "sweeps have no per-point time: processed "
                   "without deskew (the trajectory will drift with fast rotation)")
        return image.points
    t_end = sweep.stamp + float(image.point_time.max(initial=0.0))
    if track is not None and not track.covers(sweep.stamp, t_end):
        _warn_once(st, warnings, events, sweep.stamp, "no_cover", f"IMU does not cover the sweep at "
                   f"{sweep.stamp:.3f} s: rotation deskew clamped to the IMU span")
    v_sensor = None
    if cfg.deskew_translation and st.velocity is not None and st.pose is not None:
        v_sensor = st.pose[:3, :3].T @ st.velocity
    return deskew(image.points, image.point_time, sweep.stamp, track, v_sensor)


def _warn_once(st: _State, warnings: list[str], events: list[SlamEvent], t: float, key: str, text: str) -> None:
    """A condition that holds for the whole log: one warning (and one event at its first sweep)."""
    if key not in st.warned:
        st.warned.add(key)
        warnings.append(text)
        events.append(SlamEvent(t, "warning", text))


def _guess(st: _State, t: float, track: ImuTrack | None, odom: ImuOdometry | None, imu: ImuSeries | None,
           extr: np.ndarray, cfg: SlamConfig) -> np.ndarray:
    """Initial pose: IMU attitude for the first sweep; then graph #2's prediction, else the IMU
    rotation increment with constant velocity, else constant velocity."""
    if st.pose is None:
        att = initial_attitude(imu, extr[:3, :3], cfg.imu, t) if imu is not None else Rotation.identity()
        return se3.make(att.as_matrix(), np.zeros(3))
    covered = track is not None and track.covers(st.t, t)
    if odom is not None and covered and odom.can_predict:  # also right after a loop restarted graph #2
        return odom.predict(st.pose, st.t, t)
    step = (st.velocity if st.velocity is not None else np.zeros(3)) * (t - st.t)
    rot = st.pose[:3, :3]
    if covered:
        rot = rot @ track.rotation_between(st.t, np.array([t]))[0].as_matrix()
    return se3.make(rot, st.pose[:3, 3] + step)


def _imu_attitude_blend(pose: np.ndarray, imu: ImuSeries | None, extr: np.ndarray, t: float,
                        cfg: SlamConfig) -> np.ndarray:
    """9-axis IMU: slerp the matched roll/pitch towards the IMU's by rpy_weight (LIO-SAM, |pitch| < 1.4 rad)."""
    if imu is None or imu.orientation_xyzw is None or cfg.imu.rpy_weight <= 0:
        return pose
    r, p, y = Rotation.from_matrix(pose[:3, :3]).as_euler("xyz")
    ir, ip, _ = initial_attitude(imu, extr[:3, :3], cfg.imu, t).as_euler("xyz")
    if abs(ip) >= 1.4:
        return pose
    w = cfg.imu.rpy_weight
    blend = Slerp([0.0, 1.0], Rotation.from_euler("xyz", [[r, p, 0.0], [ir, ip, 0.0]]))([w])[0]
    br, bp, _ = blend.as_euler("xyz")
    return se3.make(Rotation.from_euler("xyz", [br, bp, y]).as_matrix(), pose[:3, 3])


def _report_match(res: MatchResult, t: float, cfg: SlamConfig, events: list[SlamEvent]) -> None:
    if res.degenerate:
        threshold = cfg.matching.degeneracy_eigen_threshold
        events.append(SlamEvent(t, "degeneracy", f"scan-to-map degenerate: {res.n_degenerate} direction(s) with "
                                f"eigenvalue < {threshold:g} (min {res.min_eigenvalue:.1f}); "
                                "updates along them suppressed",
                                {"min_eigenvalue": res.min_eigenvalue, "directions": res.n_degenerate}))
    if not res.optimised:
        events.append(SlamEvent(t, "warning", f"too few features ({res.n_edges} edges, {res.n_surfs} planes, "
                                f"need {cfg.matching.min_edges}/{cfg.matching.min_surfs}): kept the IMU guess"))


def _is_keyframe(graph: KeyframeGraph, pose: np.ndarray, cfg: SlamConfig) -> bool:
    if not graph.poses:
        return True
    d = se3.inv(graph.poses[-1]) @ pose
    return bool(np.linalg.norm(d[:3, 3]) >= cfg.graph.keyframe_dist_m
                or np.any(np.abs(se3.rpy(d)) >= cfg.graph.keyframe_angle_rad))


def _local_map(graph: KeyframeGraph, feats: list[Features], cache: dict, cfg: SlamConfig) -> LocalMap:
    """Keyframes within map_radius of the last one, thinned to one per keyframe_density voxel
    (the nearest to the voxel centroid), plus every keyframe of the last map_recent_s."""
    m = cfg.matching
    pos = np.array([p[:3, 3] for p in graph.poses])
    t = np.asarray(graph.stamps)
    near = np.flatnonzero(np.linalg.norm(pos - pos[-1], axis=1) <= m.map_radius_m)
    if m.keyframe_density_m > 0 and near.size > 1:
        key = np.floor(pos[near] / m.keyframe_density_m).astype(np.int64)
        _, first = np.unique(key, axis=0, return_index=True)
        near = near[first]
    chosen = np.union1d(near, np.flatnonzero(t >= t[-1] - m.map_recent_s))
    if len(cache) > m.map_cache_size:
        cache.clear()
    edges, surfs = [], []
    for i in chosen:
        if i not in cache:
            cache[i] = (se3.apply(graph.poses[i], feats[i].edges), se3.apply(graph.poses[i], feats[i].surfs))
        edges.append(cache[i][0])
        surfs.append(cache[i][1])
    return LocalMap.build(voxel_downsample(np.vstack(edges), m.corner_leaf_m),
                          voxel_downsample(np.vstack(surfs), m.surf_leaf_m))


def _try_loop(graph: KeyframeGraph, feats: list[Features], cfg: SlamConfig, events: list[SlamEvent],
              stamp: float) -> float | None:
    """Radius search for an old keyframe, ICP of the latest keyframe cloud onto the old one's
    submap, a loop factor when ICP converged with fitness below the threshold. Returns how far
    (m) the optimisation moved the latest keyframe, or None without a loop factor."""
    lc = cfg.loop
    prev = loop_candidate(graph, lc)
    if prev is None:
        return None
    cur = len(graph.poses) - 1
    src = voxel_downsample(se3.apply(graph.poses[cur], np.r_[feats[cur].edges, feats[cur].surfs]), lc.leaf_m)
    lo, hi = max(0, prev - lc.neighbours), min(cur, prev + lc.neighbours + 1)
    tgt = voxel_downsample(np.vstack([se3.apply(graph.poses[i], np.r_[feats[i].edges, feats[i].surfs])
                                      for i in range(lo, hi)]), lc.leaf_m)
    if len(src) < lc.min_source_points or len(tgt) < lc.min_target_points:
        return None
    T, fitness, ok = register_loop(src, tgt, np.eye(4), lc)
    if not ok or fitness > lc.fitness_threshold_m2:
        return None
    corrected = T @ graph.poses[cur]
    relative = se3.inv(graph.poses[prev]) @ corrected
    before = graph.poses[cur][:3, 3].copy()
    try:
        graph.add_loop(cur, prev, relative, fitness)
    except ProcessingError as err:
        events.append(SlamEvent(stamp, "warning", f"loop closure {cur} -> {prev} rejected by the solver: {err}"))
        return None
    moved = float(np.linalg.norm(graph.poses[cur][:3, 3] - before))
    events.append(SlamEvent(stamp, "loop_closure", f"keyframe {cur} -> {prev}, fitness {fitness:.3f} m^2, "
                            f"moved {moved:.3f} m",
                            {"current": cur, "previous": prev, "fitness": fitness,
                             "correction_m": float(np.linalg.norm(T[:3, 3]))}))
    return moved
