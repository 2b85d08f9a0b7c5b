"""A wheel odometry whose driver publishes only the twist (the pose stays at the origin): read by its
pose the machine would stand all log (open loop, calibrated wheels: 4.8 m online APE against 0.026 m),
so the SLAM dead-reckons the twist instead, and says so (commands/slam_wheels.py `read_wheel_track`,
slam/wheel_calibration.py `track_from_twist`). Negative controls: a moving pose is read as it is, and
a log that stands all along (pose and twist still) keeps its pose."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from mrnc_eval.commands.slam_wheels import read_wheel_track
from mrnc_eval.data import Trajectory, Twists
from mrnc_eval.slam.config import SlamConfig
from mrnc_eval.slam.wheel_calibration import track_from_twist

T = np.arange(0.0, 20.0, 0.02)
V, W = 1.0, 0.1  # m/s, rad/s: a 10 m circle


def test_a_twist_is_dead_reckoned_along_its_arc() -> None:
    track = track_from_twist(T, np.full(T.size, V), np.full(T.size, W))
    yaw = W * T[-1]
    expected = np.array([np.sin(yaw), 1.0 - np.cos(yaw)]) * V / W
    assert np.allclose(track.positions[-1, :2], expected, atol=1e-4)
    assert np.allclose(track.positions[:, 2], 0.0)


@dataclass
class _Log:
    """The two reads read_wheel_track makes of a log, and its role table."""

    positions: np.ndarray
    v: float
    roles: ClassVar[dict[str, str]] = {"wheel_odom": "/odom"}

    def has_role(self, role: str) -> bool:
        return role in self.roles

    def wheel_odometry(self) -> Trajectory:
        quat = np.tile([0.0, 0.0, 0.0, 1.0], (T.size, 1))
        return Trajectory(T, self.positions, quat)

    def odometry_twist(self) -> Twists:
        return Twists(T, np.full(T.size, self.v), np.full(T.size, W if self.v else 0.0))


def test_a_frozen_pose_with_a_moving_twist_is_dead_reckoned() -> None:
    track, note = read_wheel_track(_Log(np.zeros((T.size, 3)), V), SlamConfig())  # type: ignore[arg-type]
    assert track is not None
    assert np.ptp(track.positions[:, 0]) > 5.0
    assert "/odom" in note
    assert "twist" in note


@pytest.mark.parametrize(("positions", "v"), [(np.c_[T, np.zeros((T.size, 2))], V), (np.zeros((T.size, 3)), 0.0)])
def test_a_moving_pose_or_a_standing_log_keeps_its_pose(positions: np.ndarray, v: float) -> None:
    track, note = read_wheel_track(_Log(positions, v), SlamConfig())  # type: ignore[arg-type]
    assert track is not None
    assert np.array_equal(track.positions, positions)
    assert note == ""
