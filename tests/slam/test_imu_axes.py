"""The IMU's axes against the machine's turns (slam/imu_axes.py): a ground vehicle turns about
base_link z, on a slope too; terrain waves pitch it back and forth. Negative controls: the same drive
with the IMU's axes 90 deg off must read rotated; a straight drive over waves is not measurable (with
2 s windows and a 0.1 rad floor its pitching read as a turn about y)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from mrnc_eval.commands.slam import LogInputs, _add_imu_axes
from mrnc_eval.config import Config, replace_path
from mrnc_eval.data import ImuSeries
from mrnc_eval.results import RunResult
from mrnc_eval.slam.config import ImuAxesConfig
from mrnc_eval.slam.imu_axes import imu_axes

RATE_HZ = 100.0


def _gyro(*, turns: bool, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(stamps, angular rate in base axes) of a 60 s drive at 1 m/s over 3 m terrain waves (pitch
    +-4 deg), with turns at +-0.2 rad/s for 6 s of every 15 when `turns` (on a slope too the machine
    turns about its own z: base axes do not see the slope). Vibration 0.01 rad/s."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 60.0, 1.0 / RATE_HZ)
    pitch_rate = np.radians(4.0) * (2 * np.pi / 3.0) * np.cos(2 * np.pi * t / 3.0)
    yaw_rate = np.where((t % 15.0) > 9.0, 0.2 * np.sign(np.sin(t / 7.0)), 0.0) if turns else np.zeros(t.size)
    w = np.c_[np.zeros(t.size), pitch_rate, yaw_rate] + rng.normal(0.0, 0.01, (t.size, 3))
    return t, w


def _rotated(w: np.ndarray, deg: float) -> np.ndarray:
    a = np.radians(deg)
    r = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    return w @ r.T


def test_turns_about_base_z_are_ok() -> None:
    check = imu_axes(*_gyro(turns=True), ImuAxesConfig())
    assert check.verdict == "ok", check
    assert check.angle_deg < 5.0
    assert check.turned_rad > 2.0  # four 1.2 rad turns, split across 5 s windows: 3.6 rad


@pytest.mark.parametrize("deg", [90.0, 45.0])
def test_an_imu_whose_axes_are_off_reads_rotated(deg: float) -> None:
    t, w = _gyro(turns=True)
    check = imu_axes(t, _rotated(w, deg), ImuAxesConfig())
    assert check.verdict == "rotated", check
    assert check.angle_deg == pytest.approx(deg, abs=5.0)


def test_a_small_mount_error_is_not_flagged() -> None:
    t, w = _gyro(turns=True)
    check = imu_axes(t, _rotated(w, 10.0), ImuAxesConfig())
    assert check.verdict == "ok"
    assert check.angle_deg == pytest.approx(10.0, abs=3.0)


def test_a_straight_drive_over_waves_is_not_measurable() -> None:
    t, w = _gyro(turns=False)
    assert imu_axes(t, w, ImuAxesConfig()).verdict == "not measurable"
    short = replace(ImuAxesConfig(), window_s=1.0, min_window_rad=0.1)  # windows shorter than a wave: pitch reads
    assert imu_axes(t, w, short).verdict == "rotated"  # as a turn about y (why the defaults are 5 s / 0.25 rad)


def _result_of(deg: float, method: str = "lio") -> RunResult:
    t, w = _gyro(turns=True)
    imu = ImuSeries(t, np.tile([0.0, 0.0, 9.81], (t.size, 1)), _rotated(w, deg), None, "os_imu")
    inputs = LogInputs(duration_s=60.0, base_to_sensor=np.eye(4), imu=imu, sensor_to_imu=np.eye(4), gnss=None,
                       ground_truth=None, antenna=np.zeros(3), antenna_in_sensor=np.zeros(3), n_sweeps=600,
                       max_sweep_gap_s=0.1)
    result = RunResult(kind="slam", log_path="x.mcap", log_id="x")
    _add_imu_axes(result, inputs, replace_path(Config(), "slam.method", method))
    return result


def test_the_run_names_tf_static_when_the_imu_axes_look_rotated() -> None:
    result = _result_of(90.0)
    assert result.extra["imu_axes"]["verdict"] == "rotated"
    assert len(result.warnings) == 1
    assert "/tf_static" in result.warnings[0]
    assert "os_imu" in result.warnings[0]
    assert result.events[0].kind == "health"
    right = _result_of(0.0)  # negative controls: right axes, and kiss-icp (no IMU read)
    assert right.extra["imu_axes"]["verdict"] == "ok"
    assert not right.warnings
    assert "imu_axes" not in _result_of(90.0, "kiss-icp").extra
