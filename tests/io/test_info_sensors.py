"""`info`'s cross-checks of a log's sensors (commands/info_sensors.py) on a synthetic drive with turns:
the accelerometer's unit, the IMU's axes against the turns, the wheel clock against the gyro.
Negative controls: a log whose sensors agree has only ok findings."""

from __future__ import annotations

from dataclasses import replace
from typing import ClassVar

import numpy as np
import pytest

from mrnc_eval.commands.info_sensors import imu_and_wheel_findings, imu_in_si
from mrnc_eval.config import Config
from mrnc_eval.data import ImuSeries, Trajectory, Twists
from tests.slam.test_wheel_clock import _track_and_imu


class _Log:
    """The reads the cross-checks make: /tf_static, the wheel odometry and its twist."""

    roles: ClassVar[dict[str, str]] = {"imu": "/imu", "wheel_odom": "/odom"}

    def __init__(self, lag_s: float) -> None:
        self.track, self.imu = _track_and_imu(lag_s)
        self.imu = replace(self.imu, frame_id="imu", acc=np.tile([0.0, 0.0, 9.81], (self.imu.stamps.size, 1)))

    def static_transforms(self) -> list[tuple[str, str]]:
        return [("base_link", "imu")]

    def transform(self, parent: str, child: str) -> np.ndarray:
        return np.eye(4)

    def has_role(self, role: str) -> bool:
        return role in self.roles

    def wheel_odometry(self) -> Trajectory:
        return Trajectory(self.track.stamps, self.track.positions, self.track.quat_xyzw)

    def odometry_twist(self) -> Twists:
        raise AssertionError("a moving pose is read as it is")


def test_a_late_wheel_clock_is_a_warning_before_any_run() -> None:
    log = _Log(0.1)
    found = imu_and_wheel_findings(log, log.imu, Config())  # type: ignore[arg-type]
    warnings = [m for level, topic, m in found if level == "warning" and topic == "/odom"]
    assert len(warnings) == 1
    assert "late" in warnings[0]
    assert "slam.wheel_odom.time_offset_s=0.1" in warnings[0]
    assert any(level == "ok" and "base_link z" in m for level, _, m in found)


def test_sensors_that_agree_have_only_ok_findings() -> None:
    log = _Log(0.0)
    found = imu_and_wheel_findings(log, log.imu, Config())  # type: ignore[arg-type]
    assert {level for level, _, _ in found} == {"ok"}
    assert len(found) == 2


@pytest.mark.parametrize(("unit", "level"), [(9.80665, "warning"), (1.0, None), (1000.0, "error")])
def test_the_accelerometer_unit_is_a_finding(unit: float, level: str | None) -> None:
    t = np.arange(0.0, 10.0, 0.01)
    imu = ImuSeries(t, np.tile([0.0, 0.0, 9.81 / unit], (t.size, 1)), np.zeros((t.size, 3)), None, "imu")
    scaled, found = imu_in_si(imu, "/imu", Config())
    assert [f[0] for f in found] == ([] if level is None else [level])
    if level == "warning":
        assert np.median(scaled.acc[:, 2]) == pytest.approx(9.81, rel=1e-3)
