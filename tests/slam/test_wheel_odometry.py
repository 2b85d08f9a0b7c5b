"""Wheel odometry factor: relative motion and noise model against closed forms, and the factor
in graph #1 fixing a yaw the LiDAR left free."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mrnc_eval.geometry import se3
from mrnc_eval.slam.config import GraphConfig, WheelOdomConfig
from mrnc_eval.slam.graph import KeyframeGraph
from mrnc_eval.slam.wheel_odometry import (
    WheelTrack,
    base_sigmas,
    base_velocity,
    blend_planar,
    relative_motion,
    sensor_covariance,
    wheel_factor,
)


def _arc(radius: float, speed: float, t: np.ndarray) -> WheelTrack:
    """Planar circular arc from the origin heading +x, turning left: yaw = v t / r."""
    yaw = speed * t / radius
    pos = np.c_[radius * np.sin(yaw), radius * (1 - np.cos(yaw)), np.zeros_like(t)]
    return WheelTrack(stamps=t, positions=pos, quat_xyzw=Rotation.from_euler("z", yaw[:, None]).as_quat())


def test_relative_motion_on_an_arc_matches_the_closed_form() -> None:
    r, v = 5.0, 1.0
    track = _arc(r, v, np.linspace(0.0, 10.0, 1001))
    t0, t1 = 2.005, 3.5  # between samples: interpolated
    dyaw = v * (t1 - t0) / r
    B = se3.make(Rotation.from_euler("z", 0.3).as_matrix(), np.array([0.8, -0.2, 1.5]))  # LiDAR in base_link
    rel = relative_motion(track, t0, t1, B)
    rel_base = se3.make(Rotation.from_euler("z", dyaw).as_matrix(),
                        np.array([r * np.sin(dyaw), r * (1 - np.cos(dyaw)), 0.0]))
    expected = np.linalg.inv(B) @ rel_base @ B
    np.testing.assert_allclose(rel, expected, atol=1e-4)
    # the lever arm matters: the LiDAR's own motion differs from base_link's on a turn
    assert np.linalg.norm(rel[:3, 3] - rel_base[:3, 3]) > 0.1


def test_sigmas_grow_with_distance_and_turn() -> None:
    cfg = WheelOdomConfig()
    straight = se3.make(np.eye(3), np.array([2.0, 0.0, 0.0]))
    s = base_sigmas(straight, cfg)
    assert s[3] == pytest.approx(cfg.forward_fraction * 2 + cfg.forward_floor_m)
    assert s[4] == pytest.approx(cfg.lateral_fraction * 2 + cfg.lateral_floor_m)
    assert s[2] == pytest.approx(cfg.yaw_floor_rad)  # no turn: the floor
    turn = se3.make(Rotation.from_euler("z", 0.5).as_matrix(), np.zeros(3))
    assert base_sigmas(turn, cfg)[2] == pytest.approx(cfg.yaw_fraction * 0.5 + cfg.yaw_floor_rad)


def test_covariance_in_the_lidar_frame_follows_the_adjoint() -> None:
    """A yaw error of base_link moves a LiDAR mounted 1 m ahead sideways: the LiDAR-frame
    covariance has lateral variance sigma_yaw^2 * 1 m^2 added (closed form for this mount)."""
    cfg = WheelOdomConfig()
    B = se3.make(np.eye(3), np.array([1.0, 0.0, 0.0]))
    rel_base = se3.make(np.eye(3), np.array([1.0, 0.0, 0.0]))
    s = base_sigmas(rel_base, cfg)
    cov = sensor_covariance(rel_base, B, cfg)
    assert cov[2, 2] == pytest.approx(s[2] ** 2)
    # exp of a base yaw error e seen from the LiDAR: B^-1 exp(e) B moves the LiDAR by e x (-(-1 m))
    assert cov[4, 4] == pytest.approx(s[4] ** 2 + s[2] ** 2 * 1.0)
    assert cov[3, 3] == pytest.approx(s[3] ** 2)
    # identity mount: the base sigmas unchanged
    np.testing.assert_allclose(np.sqrt(np.diag(sensor_covariance(rel_base, np.eye(4), cfg))), s)


def test_no_factor_outside_the_odometry_span() -> None:
    track = _arc(5.0, 1.0, np.linspace(0.0, 1.0, 11))
    assert wheel_factor(track, 0.5, 1.5, np.eye(4), WheelOdomConfig()) is None
    assert wheel_factor(track, 0.2, 0.8, np.eye(4), WheelOdomConfig()) is not None


def _chain(wheel: bool) -> np.ndarray:
    """Keyframes 1 m apart along x where the 'LiDAR' (here: a biased gyro) turns 0.02 rad per step
    and left yaw free (degenerate); the wheels say straight. Returns the final keyframe poses."""
    graph = KeyframeGraph(cfg=GraphConfig())
    loose = np.array([[0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0], [0, 0, 0, 0, 1, 0]], float)  # yaw, x, y (map)
    straight = np.linspace(0.0, 10.0, 11)
    track = WheelTrack(stamps=straight, positions=np.c_[straight, np.zeros((11, 2))],
                       quat_xyzw=np.tile([0, 0, 0, 1.0], (11, 1)))
    cfg = WheelOdomConfig()
    pose = np.eye(4)
    for k in range(11):
        if k:
            pose = graph.poses[-1] @ se3.make(Rotation.from_euler("z", 0.02).as_matrix(), np.array([1.0, 0, 0]))
        factor = wheel_factor(track, float(k - 1), float(k), np.eye(4), cfg) if wheel and k else None
        graph.add_keyframe(pose, float(k), loose if k else None, factor, 1.0)  # LiDAR factor loose (1 rad, 1 m) there
    return np.array(graph.poses)


def test_wheel_factor_straightens_a_yaw_the_lidar_left_free() -> None:
    with_wheels, without = _chain(True), _chain(False)
    yaw_with = abs(se3.rpy(with_wheels[-1])[2])
    yaw_without = abs(se3.rpy(without[-1])[2])
    assert yaw_without == pytest.approx(0.2, abs=1e-3)  # negative control: the gyro's bend stays
    assert yaw_with < 0.02
    assert abs(with_wheels[-1][1, 3]) < 0.1 < abs(without[-1][1, 3])


def test_base_velocity_on_an_arc_is_forward_speed() -> None:
    track = _arc(5.0, 1.2, np.linspace(0.0, 10.0, 1001))
    v = base_velocity(track, 4.0)
    assert v is not None
    np.testing.assert_allclose(v, [1.2, 0.0, 0.0], atol=2e-3)  # body axes: forward only
    assert base_velocity(track, 9.99) is None


def test_blend_planar_takes_x_y_yaw_from_the_wheels_and_the_rest_from_the_imu() -> None:
    tilted = se3.make(Rotation.from_euler("ZYX", [0.3, 0.05, -0.02]).as_matrix(), np.array([1.0, 2.0, 3.0]))
    planar = se3.make(Rotation.from_euler("ZYX", [-0.1, 0.0, 0.0]).as_matrix(), np.array([4.0, 5.0, 6.0]))
    out = blend_planar(tilted, planar)
    np.testing.assert_allclose(Rotation.from_matrix(out[:3, :3]).as_euler("ZYX"), [-0.1, 0.05, -0.02], atol=1e-12)
    np.testing.assert_allclose(out[:3, 3], [4.0, 5.0, 3.0])
