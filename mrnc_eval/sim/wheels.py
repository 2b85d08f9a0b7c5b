"""Drive-train signals from the closed-loop trace: per-side measured wheel speeds (encoder surface
speed, so wheel slip makes odometry drift), pump commands, cmd_vel, and body wheel odometry
integrated from the measured speeds (dead reckoning, planar, as the robot's odometry node).

The measured speeds can carry a real machine's odometry errors (`WheelErrors`, sim.wheels.*):
a common scale error (effective rolling radius), a left/right radius mismatch, skid in turns (the
odometry node's yaw = track_factor x the true yaw: the effective track is wider than the geometric
one it divides by), white speed noise of the speed pickups and a yaw-rate bias."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from mrnc_eval.data import Trajectory, Twists
from mrnc_eval.sim.config import WheelSimConfig


@dataclass(frozen=True, kw_only=True)
class WheelErrors:
    """The errors drawn for one log (recorded in its metadata so tests know the truth)."""

    scale_error: float = 0.0  # both sides' speeds x (1 + scale_error)
    lr_mismatch: float = 0.0  # right x (1 + lr/2), left x (1 - lr/2): the yaw rate gains lr x v / track
    track_factor: float = 1.0  # the speed difference x this: wheel yaw = factor x true yaw
    speed_noise_mps: float = 0.0  # 1-sigma white noise per side and sample, m/s
    yaw_rate_bias_rad_s: float = 0.0  # constant yaw-rate offset of the odometry, rad/s

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def draw_wheel_errors(cfg: WheelSimConfig, errors_on: bool, rng: np.random.Generator) -> WheelErrors:
    """The configured magnitudes with random signs (the sign of a radius error is not known in
    advance); exact wheels when `errors_on` is False. The track factor and noise keep their values."""
    if not errors_on:
        return WheelErrors()
    sign = rng.choice([-1.0, 1.0], size=3) if cfg.random_signs else np.ones(3)
    return WheelErrors(scale_error=float(sign[0] * cfg.scale_error), lr_mismatch=float(sign[1] * cfg.lr_mismatch),
                       track_factor=float(cfg.track_factor), speed_noise_mps=float(cfg.speed_noise_mps),
                       yaw_rate_bias_rad_s=float(sign[2] * cfg.yaw_rate_bias_rad_s))


def measured_speeds(vl: np.ndarray, vr: np.ndarray, track_width_m: float, err: WheelErrors,
                    rng: np.random.Generator | None) -> tuple[np.ndarray, np.ndarray]:
    """Surface speeds (m/s) as the pickups report them: skid (difference x track_factor), yaw-rate
    bias (as a speed difference), radius scale and mismatch, then white noise per side."""
    v, half_diff = 0.5 * (vl + vr), 0.5 * (vr - vl) * err.track_factor
    half_diff = half_diff + 0.5 * err.yaw_rate_bias_rad_s * track_width_m
    left = (v - half_diff) * (1 + err.scale_error) * (1 - 0.5 * err.lr_mismatch)
    right = (v + half_diff) * (1 + err.scale_error) * (1 + 0.5 * err.lr_mismatch)
    if err.speed_noise_mps > 0 and rng is not None:
        left = left + rng.normal(0.0, err.speed_noise_mps, left.shape)
        right = right + rng.normal(0.0, err.speed_noise_mps, right.shape)
    return left, right


@dataclass(frozen=True)
class DriveSignals:
    stamps: np.ndarray  # (N,) s
    wheel_rad_s: np.ndarray  # (N, 2) left, right wheel angular speed, rad/s
    pump_rpm: np.ndarray  # (N, 2) left, right pump command, RPM
    cmd_vel: Twists  # commanded body twist (m/s, rad/s)
    odometry: Trajectory  # odom -> base_link, integrated from the wheel speeds
    odom_v: np.ndarray  # (N,) m/s body forward speed from the wheels
    odom_omega: np.ndarray  # (N,) rad/s yaw rate from the wheels


def drive_signals(trace, times: np.ndarray, wheel_radius_m: float, track_width_m: float,
                  errors: WheelErrors | None = None, rng: np.random.Generator | None = None) -> DriveSignals:
    """Resample the trace at `times` (s, uniform), apply the wheel `errors` (none: exact) and
    dead-reckon the wheel odometry from the trace's start pose (skid-steer: v = (vl + vr) / 2,
    omega = (vr - vl) / Lr)."""
    def at(a):
        return np.interp(times, trace.t, a)

    vl, vr = at(trace.v_wheel_left), at(trace.v_wheel_right)
    if errors is not None:
        vl, vr = measured_speeds(vl, vr, track_width_m, errors, rng)
    v, w = 0.5 * (vl + vr), (vr - vl) / track_width_m
    dt = np.diff(times, prepend=times[0])
    yaw = float(trace.yaw[0]) + np.cumsum(w * dt)
    # midpoint heading over each step (second-order dead reckoning)
    yaw_mid = yaw - 0.5 * w * dt
    x = float(trace.x[0]) + np.cumsum(v * np.cos(yaw_mid) * dt)
    y = float(trace.y[0]) + np.cumsum(v * np.sin(yaw_mid) * dt)
    q = Rotation.from_euler("z", yaw[:, None]).as_quat()
    odom = Trajectory(np.asarray(times, float), np.c_[x, y, np.zeros_like(x)], q, name="wheel_odom",
                      frame_id="odom", child_frame_id="base_link")
    cmd = Twists(np.asarray(times, float), at(trace.cmd_v), at(trace.cmd_omega))
    return DriveSignals(np.asarray(times, float), np.c_[vl, vr] / wheel_radius_m,
                        np.c_[at(trace.u_left), at(trace.u_right)], cmd, odom, v, w)
