"""The wheel clock check (slam/wheel_clock.py) on synthetic drives with a known wheel stamp lag: the
wheels' yaw is the gyro's true yaw times a skid factor, plus an L/R term and noise, stamped late.
Negative controls: wheels on time, a straight drive (no turn to time by), and wheels of another drive."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from mrnc_eval.commands.slam_wheels import clock_checked, clock_warning
from mrnc_eval.data import ImuSeries
from mrnc_eval.slam.config import SlamConfig, WheelClockConfig
from mrnc_eval.slam.wheel_clock import wheel_clock
from mrnc_eval.slam.wheel_odometry import WheelTrack

T_END = 60.0  # s


def _yaw_rate(t: np.ndarray, seed: int) -> np.ndarray:
    """A drive of straights and turns (0.1-0.4 rad/s either way, 3-6 s each), ramps of ~0.3 s, rad/s."""
    rng = np.random.default_rng(seed)
    edges = np.cumsum(rng.uniform(3.0, 6.0, 40))
    levels = np.where(np.arange(40) % 2 == 0, 0.0, rng.uniform(0.1, 0.4, 40) * rng.choice([-1.0, 1.0], 40))
    steps = levels[np.searchsorted(edges, t).clip(max=39)]
    kernel = np.ones(30) / 30  # 0.3 s at 100 Hz: the machine's yaw rate does not jump
    return np.convolve(steps, kernel, mode="same")


def _drive(lag_s: float, *, seed: int = 0, straight: bool = False, other_seed: int | None = None
           ) -> tuple[np.ndarray, ...]:
    """(wheel stamps, wheel cumulative yaw, wheel cumulative distance, gyro stamps, gyro yaw rate):
    gyro at 100 Hz (noise 0.02 rad/s, bias 0.01), wheels at 50 Hz stamped lag_s late (skid 1.6,
    L/R 2 %, 0.05 m/s pickup noise per side on a 1.9 m track), 1 m/s."""
    rng = np.random.default_rng([seed, 1])
    t = np.arange(0.0, T_END, 0.01)
    w = np.zeros(t.size) if straight else _yaw_rate(t, seed)
    gyro = w + 0.01 + rng.normal(0.0, 0.02, t.size)
    tw = np.arange(0.0, T_END, 0.02)
    w_wheels = np.zeros(t.size) if straight else _yaw_rate(t, seed if other_seed is None else other_seed)
    true_yaw = np.interp(tw, t, np.r_[0.0, np.cumsum(0.5 * (w_wheels[1:] + w_wheels[:-1])) * 0.01])  # trapezoid
    dist = 1.0 * tw
    yaw = 1.6 * true_yaw + 0.02 / 1.9 * dist + np.cumsum(rng.normal(0.0, 0.05 * np.sqrt(2) / 1.9 * 0.02, tw.size))
    return tw + lag_s, yaw, dist, t, gyro


@pytest.mark.parametrize("lag_s", [0.1, 0.05, -0.08, 0.25])
def test_a_wheel_clock_off_is_found_within_7_ms(lag_s: float) -> None:
    clock = wheel_clock(*_drive(lag_s), WheelClockConfig())
    assert abs(clock.offset_s - lag_s) < 0.007, clock  # measured within 3.4 ms on seeds 0-4
    assert clock.verdict == ("late" if lag_s > 0 else "early")
    assert clock.sigma_s < 0.008  # measured 1.6-3.6 ms


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_wheels_on_time_are_ok(seed: int) -> None:
    clock = wheel_clock(*_drive(0.0, seed=seed), WheelClockConfig())
    assert abs(clock.offset_s) < 0.007, clock
    assert clock.verdict == "ok"


def test_a_straight_drive_cannot_time_the_wheels() -> None:
    """Negative control: no change of yaw rate, nothing to time by; a lag there is not flagged."""
    clock = wheel_clock(*_drive(0.1, straight=True), WheelClockConfig())
    assert clock.verdict == "not measurable", clock
    assert clock.sigma_s > WheelClockConfig().max_sigma_s


def test_wheels_of_another_drive_are_not_timed() -> None:
    """Negative control: wheels that turn when the gyro does not share no lag with it."""
    clock = wheel_clock(*_drive(0.1, other_seed=7), WheelClockConfig())
    assert clock.verdict not in ("late", "early"), clock


def test_too_short_an_overlap_says_so() -> None:
    tw, yaw, dist, t, gyro = _drive(0.0)
    clock = wheel_clock(tw[:20], yaw[:20], dist[:20], t, gyro, WheelClockConfig())
    assert clock.verdict == "not measurable"
    assert "too few" in clock.reasons[0]


def _track_and_imu(lag_s: float) -> tuple[WheelTrack, ImuSeries]:
    tw, yaw, dist, t, gyro = _drive(lag_s)
    heading = yaw / 1.6
    pos = np.c_[np.r_[0.0, np.cumsum(np.cos(heading[:-1]) * np.diff(dist))],
                np.r_[0.0, np.cumsum(np.sin(heading[:-1]) * np.diff(dist))], np.zeros(tw.size)]
    quat = np.c_[np.zeros((tw.size, 2)), np.sin(yaw / 2), np.cos(yaw / 2)]
    imu = ImuSeries(t, np.tile([0.0, 0.0, 9.81], (t.size, 1)), np.c_[np.zeros((t.size, 2)), gyro], None, "imu")
    return WheelTrack(stamps=tw, positions=pos, quat_xyzw=quat), imu


def test_a_flagged_offset_is_taken_out_of_the_wheel_stamps() -> None:
    track, imu = _track_and_imu(0.1)
    fixed, clock = clock_checked(track, imu, np.eye(4), SlamConfig())
    assert clock is not None
    assert clock.verdict == "late"
    assert fixed is not None
    assert np.allclose(track.stamps - fixed.stamps, clock.offset_s)
    assert clock.applied_s == clock.offset_s
    text = clock_warning(clock, 0.02)
    assert text is not None
    assert "late" in text
    assert f"slam.wheel_odom.time_offset_s={0.02 + clock.offset_s:.3f}" in text


def test_wheels_on_time_or_apply_off_keep_their_stamps() -> None:
    """Negative controls: nothing flagged, or the correction switched off."""
    track, imu = _track_and_imu(0.0)
    same, clock = clock_checked(track, imu, np.eye(4), SlamConfig())
    assert clock is not None
    assert clock.verdict == "ok"
    assert clock.applied_s == 0.0
    assert same is track
    assert clock_warning(clock, 0.0) is None
    late, imu = _track_and_imu(0.1)
    cfg = SlamConfig()
    cfg = replace(cfg, wheel_odom=replace(cfg.wheel_odom, clock=replace(cfg.wheel_odom.clock, apply=False)))
    kept, clock = clock_checked(late, imu, np.eye(4), cfg)
    assert clock is not None
    assert clock.verdict == "late"
    assert clock.applied_s == 0.0
    assert kept is late
    assert "not applied" in (clock_warning(clock, 0.0) or "")


def test_wheels_that_never_turn_are_not_timed() -> None:
    """A frozen odometry pose (a twist-only driver read by its pose): every lag fits it equally, and a
    jackknife over equal costs reads 0 s; it must say not measurable, not flag an offset."""
    tw, yaw, dist, t, gyro = _drive(0.0)
    clock = wheel_clock(tw, np.zeros_like(yaw), np.zeros_like(dist), t, gyro, WheelClockConfig())
    assert clock.verdict == "not measurable", clock
    assert "factor" in clock.reasons[0]


def test_an_offset_beyond_the_search_is_not_applied() -> None:
    """0.6 s late against a +-0.4 s search: the fit's best lag sits at the edge; the run must not take
    out 0.4 s as if it were the offset. Negative control: the same lag inside a +-0.8 s search is found."""
    clock = wheel_clock(*_drive(0.6), WheelClockConfig())
    assert clock.verdict == "not measurable", clock
    assert "edge" in clock.reasons[0]
    wide = wheel_clock(*_drive(0.6), replace(WheelClockConfig(), max_lag_s=0.8))
    assert wide.verdict == "late"
    assert abs(wide.offset_s - 0.6) < 0.007
