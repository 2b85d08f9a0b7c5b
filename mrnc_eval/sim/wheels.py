"""Drive-train signals from the closed-loop trace: per-side measured wheel speeds (encoder surface
speed, so wheel slip makes odometry drift), pump commands, cmd_vel, and body wheel odometry
integrated from the measured speeds (dead reckoning, planar, as the robot's odometry node)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from mrnc_eval.data import Trajectory, Twists


@dataclass(frozen=True)
class DriveSignals:
    stamps: np.ndarray  # (N,) s
    wheel_rad_s: np.ndarray  # (N, 2) left, right wheel angular speed, rad/s
    pump_rpm: np.ndarray  # (N, 2) left, right pump command, RPM
    cmd_vel: Twists  # commanded body twist (m/s, rad/s)
    odometry: Trajectory  # odom -> base_link, integrated from the wheel speeds
    odom_v: np.ndarray  # (N,) m/s body forward speed from the wheels
    odom_omega: np.ndarray  # (N,) rad/s yaw rate from the wheels


def drive_signals(trace, times: np.ndarray, wheel_radius_m: float, track_width_m: float) -> DriveSignals:
    """Resample the trace at `times` (s, uniform) and dead-reckon the wheel odometry from the
    trace's start pose (skid-steer: v = (vl + vr) / 2, omega = (vr - vl) / Lr)."""
    def at(a):
        return np.interp(times, trace.t, a)

    vl, vr = at(trace.v_wheel_left), at(trace.v_wheel_right)
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
