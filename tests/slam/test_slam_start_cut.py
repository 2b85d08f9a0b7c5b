"""`slam --start S` reads a log as if it began S s in: the IMU, GNSS and wheel odometry are cut at
S as well as the sweeps, so the IMU set-up and the wheel calibration cannot see a standing start
before it (commands/slam.py `_inputs_from`, `_from_start`). Negative control: no window, no cut."""

from __future__ import annotations

import numpy as np
import pytest

from mrnc_eval.commands.slam import LogInputs, SweepWindow, _from_start, _inputs_from
from mrnc_eval.data import GnssSeries, ImuSeries
from mrnc_eval.slam.wheel_odometry import WheelTrack

T0 = 100.0  # the log's first message, s


def _inputs() -> LogInputs:
    t = T0 + np.arange(0.0, 10.0, 0.01)
    imu = ImuSeries(t, np.tile([0.0, 0.0, 9.81], (t.size, 1)), np.zeros((t.size, 3)), None, "imu")
    tg = T0 + np.arange(0.0, 10.0, 1.0)
    gnss = GnssSeries(stamps=tg, lla=np.zeros((tg.size, 3)), enu=np.c_[tg - T0, np.zeros((tg.size, 2))],
                      covariance=np.tile(np.eye(3), (tg.size, 1, 1)), origin_lla=np.zeros(3))
    return LogInputs(duration_s=10.0, base_to_sensor=np.eye(4), imu=imu, sensor_to_imu=np.eye(4), gnss=gnss,
                     ground_truth=None, antenna=np.zeros(3), antenna_in_sensor=np.zeros(3), n_sweeps=100,
                     max_sweep_gap_s=0.1, wheel=_wheel())


def _wheel() -> WheelTrack:
    t = T0 + np.arange(0.0, 10.0, 0.02)
    return WheelTrack(stamps=t, positions=np.c_[t - T0, np.zeros((t.size, 2))],
                      quat_xyzw=np.tile([0.0, 0.0, 0.0, 1.0], (t.size, 1)))


def test_start_cuts_imu_gnss_and_wheels_at_the_window_start() -> None:
    cut = _inputs_from(_inputs(), SweepWindow(start_s=5.0), T0)
    assert cut.imu is not None
    assert cut.gnss is not None
    assert cut.imu.stamps[0] >= T0 + 5.0
    assert cut.imu.stamps.size == 500
    assert cut.imu.gyro.shape == (500, 3)
    assert cut.imu.acc.shape == (500, 3)
    assert cut.gnss.stamps.tolist() == [T0 + s for s in (5.0, 6.0, 7.0, 8.0, 9.0)]
    assert cut.gnss.enu[0, 0] == 5.0
    assert cut.gnss.covariance.shape == (5, 3, 3)
    assert cut.wheel is not None
    assert cut.wheel.stamps.min() >= T0 + 5.0
    assert cut.wheel.stamps.size == 250
    assert cut.wheel.positions.shape == (250, 3)
    assert cut.wheel.positions[0, 0] == pytest.approx(5.0)
    wheel_stamps = T0 + np.arange(0.0, 10.0, 0.02)
    assert wheel_stamps[_from_start(wheel_stamps, SweepWindow(start_s=5.0), T0)].min() >= T0 + 5.0


def test_without_a_start_nothing_is_cut() -> None:
    """Negative controls: no window, and a window with only an end (--end cuts the sweeps only)."""
    full = _inputs()
    for window in (None, SweepWindow(end_s=5.0), SweepWindow(n_scans=10)):
        same = _inputs_from(full, window, T0)
        assert same.imu is not None
        assert same.imu.stamps.size == 1000
        assert same.gnss is not None
        assert same.gnss.stamps.size == 10
        assert same.wheel is not None
        assert same.wheel.stamps.size == 500


def test_a_start_after_every_fix_leaves_no_gnss() -> None:
    cut = _inputs_from(_inputs(), SweepWindow(start_s=9.5), T0)
    assert cut.gnss is None
    assert cut.imu is not None
    assert cut.imu.stamps.size == 50
