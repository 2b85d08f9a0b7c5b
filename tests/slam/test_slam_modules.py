"""SLAM building blocks on synthetic geometry with closed-form answers: gyro track, attitude,
preintegration, range-image columns, features on planes and corners, scan-to-map on a ray-cast
room, degeneracy in a corridor, ENU alignment, loop-closure fitness."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from mrnc_eval.data import ImuSeries, Sweep
from mrnc_eval.geometry import se3
from mrnc_eval.slam.config import FeatureConfig, ImuConfig, MatchingConfig, SensorConfig
from mrnc_eval.slam.features import extract_features
from mrnc_eval.slam.imu import ImuOdometry, clean_imu, imu_track, initial_attitude
from mrnc_eval.slam.range_image import azimuth_column, project
from mrnc_eval.slam.scan_to_map import LocalMap, match

G = 9.80511


def _imu(t: np.ndarray, gyro: np.ndarray, acc: np.ndarray) -> ImuSeries:
    return ImuSeries(t, np.broadcast_to(acc, (t.size, 3)).copy(), np.broadcast_to(gyro, (t.size, 3)).copy())


def test_gyro_track_is_exact_for_constant_rate() -> None:
    t = np.arange(0.0, 2.0, 0.01)
    w = np.array([0.1, -0.2, 0.5])
    track = imu_track(_imu(t, w, np.array([0, 0, G])), np.eye(3))
    q = np.array([0.37, 1.234, 1.5])
    got = track.rotation_between(0.3, q)
    want = Rotation.from_rotvec(np.outer(q - 0.3, w))
    assert np.max((Rotation.from_matrix(got).inv() * want).magnitude()) < 1e-9


def test_clean_imu_sorts_and_drops_duplicate_stamps() -> None:
    t = np.array([0.0, 0.02, 0.01, 0.02, 0.03])
    imu = ImuSeries(t, np.zeros((5, 3)), np.arange(15.0).reshape(5, 3))
    out = clean_imu(imu)
    assert np.all(np.diff(out.stamps) > 0)
    assert out.stamps.size == 4


def test_initial_attitude_from_accelerometer_matches_tilt() -> None:
    tilt = Rotation.from_euler("xyz", [0.1, -0.05, 0.0])
    f = tilt.inv().apply([0, 0, G])  # specific force in the tilted sensor frame at rest
    att = initial_attitude(_imu(np.arange(0, 1, 0.01), np.zeros(3), f), np.eye(3), ImuConfig())
    np.testing.assert_allclose(Rotation.from_matrix(att).as_euler("xyz"), [0.1, -0.05, 0.0], atol=1e-9)


def test_preintegration_graph_learns_velocity_and_predicts_constant_acceleration() -> None:
    """Robot accelerating at 0.5 m/s^2 along x, level: after a few lidar poses graph #2 knows the
    velocity and predicts the next pose to millimetres."""
    a = 0.5
    t = np.arange(0.0, 4.0, 0.01)
    track = imu_track(_imu(t, np.zeros(3), np.array([a, 0, G])), np.eye(3))
    odo = ImuOdometry(track, ImuConfig(), np.eye(4))
    pose_at = lambda s: se3.make(np.eye(3), np.array([0.5 * a * s * s, 0, 0]))  # noqa: E731
    for s in np.arange(0.0, 2.01, 0.2):
        assert odo.add_lidar_pose(pose_at(s), s, False) is None
    assert odo.velocity[0] == pytest.approx(a * 2.0, abs=0.02)
    pred = odo.predict(pose_at(2.0), 2.0, 2.2)
    assert np.linalg.norm(pred[:3, 3] - pose_at(2.2)[:3, 3]) < 0.005


def test_azimuth_column_follows_lio_sam_formula() -> None:
    pts = np.array([[0.0, 1.0, 0], [1.0, 0.0, 0], [0.0, -1.0, 0], [-1.0, 0.0, 0]])
    # atan2(x, y): +y is 0 deg -> column H/2 + H/4; +x is 90 deg -> H/2
    np.testing.assert_array_equal(azimuth_column(pts, 1024), [768, 512, 256, 0])


# ---------------------------------------------------------------- ray-cast scenes (open3d)
def _scene(boxes):
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    for size, centre in boxes:
        m = o3d.geometry.TriangleMesh.create_box(*size)
        m.translate(np.asarray(centre) - np.asarray(size) / 2)
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(m))
    return scene


def _room():
    """A 30 x 20 x 6 m hall (walls as thin boxes) with pillars and crates: planes and edges."""
    walls = [((30, 0.2, 6), (0, 10, 3)), ((30, 0.2, 6), (0, -10, 3)), ((0.2, 20, 6), (15, 0, 3)),
             ((0.2, 20, 6), (-15, 0, 3)), ((30, 20, 0.2), (0, 0, -0.1))]
    clutter = [((1, 1, 6), (5, 4, 3)), ((1, 1, 6), (-6, -5, 3)), ((2, 1.5, 1.5), (8, -6, 0.75)),
               ((1.5, 3, 2), (-9, 6, 1)), ((0.6, 0.6, 6), (2, -3, 3)), ((3, 0.5, 1), (-3, 7, 0.5))]
    return _scene(walls + clutter)


def _corridor():
    """A 200 m straight corridor 3 m wide: nothing constrains motion along x."""
    return _scene([((200, 0.2, 3), (0, 1.5, 1.5)), ((200, 0.2, 3), (0, -1.5, 1.5)), ((200, 3.2, 0.2), (0, 0, -0.1)),
                   ((200, 3.2, 0.2), (0, 0, 3.1))])


def _scan(scene, pose: np.ndarray, rings: int = 32, cols: int = 1024) -> Sweep:
    """Organised OS0-like scan (ring 0 = top beam, +/-45 deg) from `pose` (sensor in world)."""
    import open3d as o3d

    el = np.radians(np.linspace(45, -45, rings))
    az = np.radians(180.0 - 360.0 * np.arange(cols) / cols)  # Ouster: columns sweep clockwise from -x
    E, A = np.meshgrid(el, az, indexing="ij")
    d_s = np.stack([np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)], -1).reshape(-1, 3)
    d_w = d_s @ pose[:3, :3].T
    rays = np.c_[np.broadcast_to(pose[:3, 3], d_w.shape), d_w].astype(np.float32)
    t_hit = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
    ok = np.isfinite(t_hit) & (t_hit < 100)
    pts = (d_s[ok] * t_hit[ok, None]).astype(np.float32)
    ring, col = np.divmod(np.arange(rings * cols), cols)
    return Sweep(0.0, pts, None, ring[ok].astype(np.uint16), col[ok].astype(np.uint32), height=rings, width=cols)


def _features(sweep: Sweep):
    img = project(sweep, SensorConfig(), FeatureConfig())
    return extract_features(img, img.points, FeatureConfig())


def test_features_find_pillar_edges_and_wall_planes() -> None:
    scene = _room()
    pose = se3.make(np.eye(3), np.array([0.0, 0.0, 1.0]))
    f = _features(_scan(scene, pose))
    assert len(f.edges) > 20
    assert len(f.surfs) > 500
    world_s = se3.apply(pose, f.surfs)
    # planar points lie on a wall, floor or box face: distance to the nearest axis-aligned face is tiny
    on_face = (np.abs(np.abs(world_s[:, 1]) - 9.9) < 0.05) | (np.abs(world_s[:, 2]) < 0.05) | \
        (np.abs(np.abs(world_s[:, 0]) - 14.9) < 0.05)
    assert on_face.mean() > 0.5
    # edges concentrate on vertical box/pillar edges: their xy lies near a box corner
    corners = np.array([[x, y] for (sx, sy, _), (cx, cy, _) in
                        [((1, 1, 6), (5, 4, 3)), ((1, 1, 6), (-6, -5, 3)), ((0.6, 0.6, 6), (2, -3, 3)),
                         ((2, 1.5, 1.5), (8, -6, 0.75)), ((1.5, 3, 2), (-9, 6, 1)), ((3, 0.5, 1), (-3, 7, 0.5))]
                        for x in (cx - sx / 2, cx + sx / 2) for y in (cy - sy / 2, cy + sy / 2)]
                       + [[x, y] for x in (-14.9, 14.9) for y in (-9.9, 9.9)])
    d, _ = cKDTree(corners).query(se3.apply(pose, f.edges)[:, :2])
    assert np.mean(d < 0.3) > 0.5


def _map_from(scene, poses) -> LocalMap:
    from mrnc_eval.slam.features import voxel_downsample

    edges, surfs = [], []
    for p in poses:
        f = _features(_scan(scene, p))
        edges.append(se3.apply(p, f.edges))
        surfs.append(se3.apply(p, f.surfs))
    return LocalMap.build(voxel_downsample(np.vstack(edges), 0.2), voxel_downsample(np.vstack(surfs), 0.4))


def test_scan_to_map_recovers_a_perturbed_pose_in_a_room() -> None:
    scene = _room()
    map_poses = [se3.make(np.eye(3), np.array([x, y, 1.0])) for x, y in [(0, 0), (2, 1), (-2, -1)]]
    local = _map_from(scene, map_poses)
    truth = se3.make(Rotation.from_euler("xyz", [0.02, -0.01, 0.3]).as_matrix(), np.array([1.0, 0.5, 1.05]))
    f = _features(_scan(scene, truth))
    guess = se3.make(Rotation.from_euler("xyz", [0.0, 0.0, 0.25]).as_matrix(), np.array([1.3, 0.3, 1.0]))
    res = match(f.edges, f.surfs, local, guess, MatchingConfig())
    assert res.optimised
    assert not res.degenerate
    err = se3.inv(truth) @ res.pose
    assert np.linalg.norm(err[:3, 3]) < 0.02
    assert np.degrees(se3.delta_angle(err)) < 0.2


def test_corridor_is_degenerate_along_its_axis_and_the_update_is_suppressed() -> None:
    scene = _corridor()
    map_poses = [se3.make(np.eye(3), np.array([x, 0.0, 1.0])) for x in (0.0, 1.0, 2.0)]
    local = _map_from(scene, map_poses)
    truth = se3.make(np.eye(3), np.array([3.0, 0.0, 1.0]))
    f = _features(_scan(scene, truth))
    guess = se3.make(np.eye(3), np.array([2.6, 0.2, 1.0]))  # off along x (unobservable) and y (observable)
    res = match(f.edges, f.surfs, local, guess, MatchingConfig())
    assert res.degenerate
    assert res.n_degenerate >= 1
    assert abs(res.pose[1, 3]) < 0.02  # the observable direction is corrected
    assert abs(res.pose[0, 3] - 2.6) < 0.05  # the degenerate one is left at the guess, not driven anywhere


def test_loop_fitness_is_pcl_mean_squared_distance() -> None:
    from mrnc_eval.slam.graph import icp_fitness

    tgt = np.random.default_rng(1).uniform(-5, 5, (2000, 3))
    src = tgt[:500] + np.array([0.1, 0.0, 0.0])
    d, _ = cKDTree(tgt).query(src)
    assert icp_fitness(src, tgt, 30.0) == pytest.approx(float(np.mean(d * d)), rel=1e-12)


def test_enu_alignment_recovers_yaw_and_offset() -> None:
    from mrnc_eval.slam.gnss import fit_yaw_translation

    rng = np.random.default_rng(2)
    enu = rng.uniform(-20, 20, (30, 2))
    yaw, t = 0.7, np.array([3.0, -4.0])
    c, s = np.cos(yaw), np.sin(yaw)
    mp = enu @ np.array([[c, -s], [s, c]]).T + t
    rot, tt = fit_yaw_translation(enu, mp)
    assert np.arctan2(rot[1, 0], rot[0, 0]) == pytest.approx(yaw, abs=1e-12)
    assert np.allclose(tt, t)


def test_a_wrong_fix_moves_the_anchored_chain_little_and_lio_sams_free_start_a_lot() -> None:
    """slam.graph.anchor_start: the first keyframe anchors the map (origin and heading), so a
    float fix 2 m off along the track (a multipath jump; variance floored at 1 m^2) meets 20
    metres of stiff odometry and moves the latest keyframe by centimetres. With LIO-SAM's free
    start (negative control) the one fix slides the whole chain by over a metre."""
    from mrnc_eval.slam.config import GraphConfig
    from mrnc_eval.slam.graph import KeyframeGraph

    moved = {}
    for name, anchored in (("anchored", True), ("lio-sam", False)):
        graph = KeyframeGraph(cfg=GraphConfig(), anchored=anchored)
        for k in range(21):
            graph.add_keyframe(se3.make(np.eye(3), np.array([float(k), 0.0, 0.0])), float(k))
        before = graph.poses[-1][:3, 3].copy()
        graph.add_gps(20, np.array([22.0, 0.0, 0.0]), np.array([0.09, 0.09, 0.09]), np.zeros(3))
        moved[name] = float(np.linalg.norm(graph.poses[-1][:3, 3] - before))
    assert moved["anchored"] < 0.01  # measured 0.004 m (LIO-SAM start: 2.0 m)
    assert moved["lio-sam"] > 1.0


def test_without_wheels_the_start_is_free_and_a_residual_gate_factor_pulls_a_drifted_chain_onto_the_fix() -> None:
    """slam.graph.anchor_start=with_wheels anchors only with wheel factors, whatever the GNSS gate.
    Without wheels on bare ground the chain is IMU dead reckoning: here it read 15 % long (23 m for
    20 m). A residual-gate factor (sigma 10 cm, no floor, Huber) at the true 20 m puts the free
    chain onto the fix; the anchored start (negative control: the rule before, anchored with the
    residual gate even without wheels) keeps it ~3 m off, as on the open line (issue 28)."""
    from dataclasses import replace

    from mrnc_eval.slam.config import GraphConfig, SlamConfig
    from mrnc_eval.slam.graph import KeyframeGraph
    from mrnc_eval.slam.replay import start_anchored

    cfg = SlamConfig()
    assert cfg.gps.gate == "residual"
    assert cfg.graph.anchor_start == "with_wheels"
    assert start_anchored(cfg, with_wheels=True)
    assert not start_anchored(cfg, with_wheels=False)
    always = replace(cfg, graph=replace(cfg.graph, anchor_start="always"), gps=replace(cfg.gps, gate="lio_sam"))
    assert start_anchored(always, with_wheels=False)
    off = {}
    for anchored in (start_anchored(cfg, with_wheels=False), True):
        graph = KeyframeGraph(cfg=GraphConfig(), anchored=anchored)
        for k in range(21):
            graph.add_keyframe(se3.make(np.eye(3), np.array([1.15 * k, 0.0, 0.0])), float(k))
        graph.add_gps(20, np.array([20.0, 0.0, 0.0]), np.array([0.01, 0.01, 0.01]), np.zeros(3), floor_m2=0.0,
                      huber_k=1.345)
        off[anchored] = float(np.linalg.norm(graph.poses[-1][:3, 3] - [20.0, 0.0, 0.0]))
    assert off[False] < 0.1  # measured ~0 m
    assert off[True] > 2.0  # measured 2.97 m


def test_gnss_factors_pull_a_drifting_keyframe_chain_onto_the_fixes() -> None:
    """Graph #1 with LIO-SAM's loose first-pose prior: odometry with a 1 %/m heading drift bends
    the chain away from the truth; GNSS factors on the antenna (lever arm 0.5 m up, variance
    floored at 1 m^2 as LIO-SAM) pull it back."""
    from mrnc_eval.slam.config import GraphConfig
    from mrnc_eval.slam.graph import KeyframeGraph

    n, lever = 60, np.array([0.0, 0.0, 0.5])
    truth = [se3.make(np.eye(3), np.array([float(k), 0.0, 0.0])) for k in range(n)]
    step_drift = se3.make(Rotation.from_euler("z", 0.01).as_matrix(), np.array([1.0, 0.0, 0.0]))
    errors = {}
    for with_gnss in (False, True):
        graph = KeyframeGraph(cfg=GraphConfig())
        for k in range(n):  # each new pose continues from the optimised last one, as scan-to-map does
            graph.add_keyframe(truth[0] if k == 0 else graph.poses[-1] @ step_drift, float(k))
            if with_gnss and k % 5 == 0 and k > 0:
                antenna = truth[k][:3, 3] + lever
                graph.add_gps(k, antenna, np.array([0.01, 0.01, 0.01]), lever)
        errors[with_gnss] = max(np.linalg.norm(p[:3, 3] - t[:3, 3]) for p, t in zip(graph.poses, truth, strict=True))
    assert errors[False] > 10.0  # 0.01 rad per metre over 60 m
    assert errors[True] < 0.25 * errors[False]  # 3.2 m vs 16.9 m: stiff odometry (1 mrad) against 1 m fixes
    assert graph.gps_factors == 11


def test_deskew_matches_per_point_rotation_and_velocity() -> None:
    from mrnc_eval.slam.deskew import deskew

    t = np.arange(0.0, 1.0, 0.01)
    w = np.array([0.05, 0.02, 0.8])
    track = imu_track(_imu(t + 100.0, w, np.array([0, 0, G])), np.eye(3))
    rng = np.random.default_rng(3)
    pts = rng.uniform(-20, 20, (5000, 3))
    pt = np.sort(rng.uniform(0, 0.1, 5000))
    v = np.array([0.4, 0.0, 0.0])
    got = deskew(pts, pt.astype(np.float32), 100.2, track, v)
    want = Rotation.from_rotvec(np.outer(pt, w)).apply(pts) + np.outer(pt, v)
    # 1 ms rotation quanta: error below 0.8 rad/s * 0.5 ms * 35 m
    assert np.max(np.linalg.norm(got - want, axis=1)) < 0.8 * 0.5e-3 * 35 + 1e-6
    assert np.max(np.linalg.norm(got - pts, axis=1)) > 1.0  # a real motion was removed


def test_paper_smoothness_is_the_normalised_sum_of_differences() -> None:
    """The paper's (LOAM's) c = |sum_u (p_k - p_u)| / (|S| |p_k|): zero on a straight evenly
    sampled line, |10 p_k - sum p_u| / (10 |p_k|) at a kink, checked against numpy."""
    from mrnc_eval.slam.features import _smoothness

    x = np.linspace(-5.0, 5.0, 21)
    line = np.c_[x, np.full_like(x, 4.0), np.zeros_like(x)]
    kinked = line.copy()
    kinked[10, 1] += 0.5
    rng = np.linalg.norm(kinked, axis=1)
    c = _smoothness(rng, kinked, True)
    assert np.allclose(_smoothness(np.linalg.norm(line, axis=1), line, True)[5:-5], 0.0, atol=1e-12)
    expected = np.linalg.norm(10 * kinked[10] - kinked[5:10].sum(0) - kinked[11:16].sum(0)) / (10 * rng[10])
    assert c[10] == pytest.approx(expected, rel=1e-12)
    assert c[10] == c.max()


def test_local_map_takes_the_keyframe_nearest_to_each_voxel_centroid() -> None:
    """LIO-SAM's selection: three old keyframes in one 2 m voxel (x = 0.1, 1.0, 1.9 m) have their
    centroid at 1.0 m, so the middle one is taken; the earlier rule took the first (oldest). The
    last map_recent_s of keyframes is always in."""
    from mrnc_eval.config import Config, replace_path
    from mrnc_eval.slam.replay import _local_keyframes

    pos = np.array([[0.1, 0.5, 0.0], [1.0, 0.5, 0.0], [1.9, 0.5, 0.0], [30.0, 0.5, 0.0], [31.0, 0.5, 0.0]])
    t = np.array([0.0, 10.0, 20.0, 100.0, 105.0])
    cfg = Config().slam
    assert list(_local_keyframes(pos, t, cfg)) == [1, 3, 4]
    oldest = replace_path(Config(), "slam.matching.local_map_selection", "oldest").slam
    assert list(_local_keyframes(pos, t, oldest)) == [0, 3, 4]
