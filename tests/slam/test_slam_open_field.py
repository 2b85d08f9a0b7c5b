"""Open ground (issue 16 item 5) on ray-cast synthetic geometry: bare rough ground pins z, roll and
pitch only, so scan-to-map must leave x, y and yaw to the IMU; a loop closure on bare ground is
refused; graph #2 loosens only the degenerate directions. Each with LIO-SAM's rule as the
negative control."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from mrnc_eval.geometry import se3
from mrnc_eval.sim.scene import build_scene
from mrnc_eval.slam.config import FeatureConfig, ImuConfig, LoopConfig, MatchingConfig, SensorConfig
from mrnc_eval.slam.features import ground_mask
from mrnc_eval.slam.graph import icp_min_eigenvalue
from mrnc_eval.slam.imu import ImuOdometry, imu_track
from mrnc_eval.slam.range_image import project
from mrnc_eval.slam.scan_to_map import match
from tests.slam.test_slam_modules import _features, _imu, _map_from, _room, _scan

LIO_SAM = replace(MatchingConfig(), ground_normal_min_z=0.0, plane_min_spread_m=0.0)
YAW, X, Y = 2, 3, 4  # indices in [rot (3), trans (3)]


def _bare_ground():
    """The simulator's bare field (4 cm roughness on gentle relief), a map from three poses along
    x, and the truth and an IMU guess off by 1 deg of yaw and 0.2 / 0.1 m."""
    field = build_scene("field", seed=3, roughness_m=0.04)
    scene = field.raycasting_scene()

    def pose(x: float, yaw_deg: float = 0.0, dxy=(0.0, 0.0)) -> np.ndarray:
        z = float(field.terrain.height(np.array(x), np.array(0.0))) + 1.2
        return se3.make(Rotation.from_euler("z", yaw_deg, degrees=True).as_matrix(), np.array([x + dxy[0], dxy[1], z]))

    local = _map_from(scene, [pose(0.0), pose(1.0), pose(2.0)])
    truth = pose(3.0)
    return scene, local, truth, pose(3.0, 1.0, (0.2, 0.1))


def _span(directions: np.ndarray, axis: int) -> float:
    """Length of unit vector `axis` projected on the span of `directions` (k, 6)."""
    q, _ = np.linalg.qr(directions.T)
    return float(np.linalg.norm(q.T @ np.eye(6)[axis]))


def test_bare_ground_pins_z_roll_pitch_and_leaves_x_y_yaw_at_the_imu_guess() -> None:
    scene, local, truth, guess = _bare_ground()
    f = _features(_scan(scene, truth, cols=512))
    res = match(f.edges, f.surfs, local, guess, MatchingConfig())
    assert res.degenerate
    assert res.n_degenerate == 3
    assert res.degenerate_directions is not None
    assert min(_span(res.degenerate_directions, a) for a in (YAW, X, Y)) > 0.99
    yaw = np.degrees(Rotation.from_matrix(res.pose[:3, :3]).as_euler("xyz")[2])
    assert abs(yaw - 1.0) < 0.01  # held at the guess, not driven by rough-ground normals
    np.testing.assert_allclose(res.pose[:2, 3], guess[:2, 3], atol=0.005)
    assert abs(res.pose[2, 3] - truth[2, 3]) < 0.02  # the ground still fixes the height
    # negative control, LIO-SAM's rows: tilted rough-ground normals and nearly collinear far
    # neighbours pose as yaw information, so yaw counts as measured and is updated
    lio = match(f.edges, f.surfs, local, guess, LIO_SAM)
    assert lio.n_degenerate < 3
    assert lio.degenerate_directions is not None
    assert _span(lio.degenerate_directions, YAW) < 0.5


def test_ground_points_are_found_on_ground_and_not_on_walls() -> None:
    scene, _, truth, _ = _bare_ground()
    sweep = _scan(scene, truth, cols=512)
    img = project(sweep, SensorConfig(), FeatureConfig())
    below = img.points[:, 2] < -0.5
    assert ground_mask(img, img.points, 10.0)[below].mean() > 0.95
    room = _scan(_room(), se3.make(np.eye(3), np.array([0.0, 0.0, 1.0])))
    img = project(room, SensorConfig(), FeatureConfig())
    walls = img.points[:, 2] > 0.5  # above the sensor: walls, pillars and ceiling-less space
    assert not ground_mask(img, img.points, 10.0)[walls].any()


def test_loop_alignment_on_bare_ground_is_degenerate_and_in_a_room_is_not() -> None:
    scene, local, truth, _ = _bare_ground()
    f = _features(_scan(scene, truth, cols=512))
    bare = icp_min_eigenvalue(se3.apply(truth, f.surfs), local.surfs, truth[:3, 3], 0.9)
    room_pose = se3.make(np.eye(3), np.array([1.0, 0.5, 1.0]))
    room = _room()
    room_map = _map_from(room, [se3.make(np.eye(3), np.array([x, y, 1.0])) for x, y in [(0, 0), (2, 1), (-2, -1)]])
    fr = _features(_scan(room, room_pose))
    walls = icp_min_eigenvalue(se3.apply(room_pose, fr.surfs), room_map.surfs, room_pose[:3, 3], 0.9)
    threshold = LoopConfig().min_eigenvalue
    assert bare < 0.1 * threshold < 2 * threshold < walls


def test_graph2_prior_is_loose_only_along_the_degenerate_directions() -> None:
    t = np.arange(0.0, 1.0, 0.01)
    track = imu_track(_imu(t, np.zeros(3), np.array([0.0, 0.0, 9.80511])), np.eye(3))
    cfg = ImuConfig()
    odom = ImuOdometry(track, cfg, np.eye(4))
    rot = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    yaw_and_map_x = np.array([[0, 0, 1.0, 0, 0, 0], [0, 0, 0, 1.0, 0, 0]])  # map x = body -y after 90 deg of yaw
    cov = odom._pose_prior(rot, True, yaw_and_map_x).covariance()
    base = np.square(cfg.pose_prior_sigmas)
    loose = base + np.array([0, 0, 1, 0, 1, 0]) * cfg.degenerate_pose_sigma ** 2
    np.testing.assert_allclose(cov, np.diag(loose), atol=1e-12)
    # LIO-SAM's rule, the negative control: every direction loose, also the measured z, roll and pitch
    lio = odom._pose_prior(rot, True, None).covariance()
    np.testing.assert_allclose(np.diag(lio), np.full(6, cfg.degenerate_pose_sigma ** 2))


def test_rtk_fixes_bend_the_chain_only_where_scan_to_map_left_x_y_to_the_imu() -> None:
    """Graph #1: keyframes 1 m apart whose odometry drifts sideways ever faster (4 mm more per
    metre, as an IMU carrying a degenerate y with a tilt error does: a parabola, 3 m after 40 m,
    that no rotation of the chain removes); RTK fixes (2 cm) every 5 keyframes. With the degenerate
    directions loosened the chain follows the fixes; LIO-SAM's stiff odometry (1 cm) and 1 m^2
    floor on the fixes (the negative control) keep the bend."""
    from mrnc_eval.slam.config import GraphConfig
    from mrnc_eval.slam.graph import KeyframeGraph

    n = 40
    truth = [se3.make(np.eye(3), np.array([float(k), 0.0, 0.0])) for k in range(n)]
    loose = np.eye(6)[[X, Y]]  # x and y left to the IMU
    errors = {}
    for name, sigma, floor in (("loose", 0.1, 0.0), ("lio_sam", 0.0, 1.0)):
        graph = KeyframeGraph(cfg=replace(GraphConfig(), degenerate_odometry_sigma=sigma))
        for k in range(n):
            step = se3.make(np.eye(3), np.array([1.0, 0.004 * k, 0.0]))
            graph.add_keyframe(truth[0] if k == 0 else graph.poses[-1] @ step, float(k), loose)
            if k % 5 == 4:
                graph.add_gps(k, truth[k][:3, 3], np.full(3, 0.02 ** 2), floor_m2=floor)
        # from the first fix on (before it the chain hangs from LIO-SAM's loose first-pose prior)
        errors[name] = max(abs(p[1, 3] - t[1, 3]) for p, t in zip(graph.poses[4:], truth[4:], strict=True))
    assert errors["loose"] < 0.05
    assert errors["lio_sam"] > 0.2


def test_a_wheel_guess_holds_a_weakly_measured_yaw_and_a_room_still_corrects_it() -> None:
    """slam.wheel_odom.yaw_information: on rough bare ground a yaw-and-translation mixture passes
    the degeneracy threshold (eigenvalue ~150) and, unheld, drives the yaw 17 deg off an exact
    guess; held towards the wheel guess it stays within 0.06 deg, also with an overwhelming hold
    (solving within the measured directions: projecting the held solution afterwards turned its
    translation into 9 deg of yaw). In a hall, where the sweep measures yaw strongly, the same hold
    still corrects a 0.5 deg guess error to within 0.1 deg."""
    field = build_scene("open_field", seed=2, roughness_m=0.04)
    scene = field.raycasting_scene()

    def pose(x: float, dxy=(0.0, 0.0)) -> np.ndarray:
        z = float(field.terrain.height(np.array(x), np.array(0.0))) + 1.2
        return se3.make(np.eye(3), np.array([x + dxy[0], dxy[1], z]))

    local = _map_from(scene, [pose(0.0), pose(1.0), pose(2.0)])
    f = _features(_scan(scene, pose(3.0), cols=512))
    guess = pose(3.0, (0.2, 0.1))  # yaw exact, x and y off (the wheels' drift)

    def yaw_deg(T: np.ndarray) -> float:
        return float(np.degrees(Rotation.from_matrix(T[:3, :3]).as_euler("xyz")[2]))

    def hold(info: float) -> np.ndarray:
        return np.array([0.0, 0.0, info, 0.0, 0.0, 0.0])

    unheld = match(f.edges, f.surfs, local, guess, MatchingConfig())
    assert abs(yaw_deg(unheld.pose)) > 5.0  # negative control: the weak direction runs off
    for info in (1e4, 1e12):
        held = match(f.edges, f.surfs, local, guess, MatchingConfig(), hold(info))
        # 0.053 deg at 1e4 (neighbours re-queried per feature after 5 cm); re-querying every iteration
        # gives 0.044-0.051 deg for guesses 1-5 cm apart, so 0.05 was within the held yaw's own noise
        assert abs(yaw_deg(held.pose)) < 0.06
        assert held.degenerate  # the degeneracy test still looks at the sweep's own J^T J
    hall = _room()
    start = se3.make(np.eye(3), np.array([2.0, 0.0, 1.0]))
    hall_map = _map_from(hall, [start @ se3.make(np.eye(3), np.array([dx, 0.0, 0.0])) for dx in (-3.0, -2.0, -1.0)])
    fh = _features(_scan(hall, start))
    turned = start @ se3.make(Rotation.from_euler("z", 0.5, degrees=True).as_matrix(), np.zeros(3))
    corrected = match(fh.edges, fh.surfs, hall_map, turned, MatchingConfig(), hold(1e4))
    assert abs(yaw_deg(corrected.pose)) < 0.1


def test_a_tilt_corrected_about_the_base_keeps_the_base_where_the_wheels_put_it() -> None:
    """match(pivot=...): on bare ground x and y are held; a guess whose base is right but tilted
    1 deg in pitch gets its pitch from the ground, and turning about the base (1.9 m below and
    1.2 m behind the sensor) keeps the base in place. Turning about the sensor (negative control,
    LIO-SAM) drags the base by 1.9 m x 1 deg = 3.3 cm, which the wheels then carry on sweep after
    sweep (open field 0.11 m against 0.04 m)."""
    scene, local, truth, _ = _bare_ground()
    f = _features(_scan(scene, truth, cols=512))
    mount = se3.make(np.eye(3), np.array([1.2, 0.0, 1.9]))  # the sensor in the base frame
    base = truth @ se3.inv(mount)
    guess = base @ se3.make(Rotation.from_euler("y", 1.0, degrees=True).as_matrix(), np.zeros(3)) @ mount
    pivot = se3.inv(mount)[:3, 3]

    def base_error(res_pose: np.ndarray) -> tuple[float, float]:
        b = res_pose @ se3.inv(mount)
        pitch = np.degrees(se3.delta_angle(se3.inv(truth) @ res_pose))
        return float(np.linalg.norm(b[:2, 3] - base[:2, 3])), float(pitch)

    about_base = match(f.edges, f.surfs, local, guess, MatchingConfig(), pivot=pivot)
    moved, tilt = base_error(about_base.pose)
    assert about_base.degenerate
    assert tilt < 0.03  # measured 0.012 deg
    assert moved < 0.001  # measured 1e-6 m
    about_sensor = match(f.edges, f.surfs, local, guess, MatchingConfig())
    moved, tilt = base_error(about_sensor.pose)
    assert tilt < 0.03
    assert moved > 0.02  # measured 0.032 m
