"""The simulator's wheel-odometry error model (sim/wheels.py) and GNSS outages (sim/gnss.py):
each error shows up in the measured speeds as specified, exact wheels are untouched."""

from __future__ import annotations

import numpy as np
import pytest

from mrnc_eval.sim.config import WheelSimConfig
from mrnc_eval.sim.gnss import STATUS_NO_FIX, with_outages
from mrnc_eval.sim.wheels import WheelErrors, draw_wheel_errors, measured_speeds

TRACK = 1.6


def _yaw_rate_and_speed(err: WheelErrors, v: float, w: float, n: int = 20000) -> tuple[np.ndarray, np.ndarray]:
    vl, vr = np.full(n, v - 0.5 * w * TRACK), np.full(n, v + 0.5 * w * TRACK)
    ml, mr = measured_speeds(vl, vr, TRACK, err, np.random.default_rng(0))
    return (mr - ml) / TRACK, 0.5 * (ml + mr)


def test_each_wheel_error_as_specified() -> None:
    w_odo, _ = _yaw_rate_and_speed(WheelErrors(track_factor=1.6), 1.0, 0.2)
    assert w_odo.mean() == pytest.approx(1.6 * 0.2)  # skid: wheel yaw = factor x true yaw
    w_odo, _ = _yaw_rate_and_speed(WheelErrors(lr_mismatch=0.02), 1.0, 0.0)
    assert w_odo.mean() == pytest.approx(0.02 * 1.0 / TRACK)  # L/R: a yaw rate proportional to speed
    _, v_odo = _yaw_rate_and_speed(WheelErrors(scale_error=-0.02), 1.0, 0.0)
    assert v_odo.mean() == pytest.approx(0.98)
    w_odo, _ = _yaw_rate_and_speed(WheelErrors(yaw_rate_bias_rad_s=0.01), 0.0, 0.0)
    assert w_odo.mean() == pytest.approx(0.01)
    w_odo, v_odo = _yaw_rate_and_speed(WheelErrors(speed_noise_mps=0.05), 1.0, 0.0)
    assert v_odo.std() == pytest.approx(0.05 / np.sqrt(2), rel=0.05)
    assert w_odo.std() == pytest.approx(0.05 * np.sqrt(2) / TRACK, rel=0.05)
    w_odo, v_odo = _yaw_rate_and_speed(WheelErrors(), 1.0, 0.2)  # exact: untouched
    assert np.allclose(w_odo, 0.2)
    assert np.allclose(v_odo, 1.0)


def test_drawn_errors_keep_magnitudes_and_exact_means_none() -> None:
    cfg = WheelSimConfig(scale_error=0.02, lr_mismatch=0.02, track_factor=1.6)
    signs = set()
    for seed in range(8):
        e = draw_wheel_errors(cfg, True, np.random.default_rng(seed))
        assert abs(e.scale_error) == pytest.approx(0.02)
        assert abs(e.lr_mismatch) == pytest.approx(0.02)
        assert e.track_factor == pytest.approx(1.6)
        signs.add(np.sign(e.lr_mismatch))
    assert signs == {-1.0, 1.0}
    assert draw_wheel_errors(cfg, False, np.random.default_rng(0)) == WheelErrors()


def test_gnss_outages_are_no_fix() -> None:
    t = np.arange(0.0, 10.0, 0.2)
    status = with_outages(t, np.full(t.size, 2), ((2.0, 3.0), (7.0, 7.5)))
    out = (t >= 2.0) & (t < 3.0) | (t >= 7.0) & (t < 7.5)
    assert np.all(status[out] == STATUS_NO_FIX)
    assert np.all(status[~out] == 2)
