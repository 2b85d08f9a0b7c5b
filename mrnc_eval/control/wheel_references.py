"""Per-side wheel-speed references of a run without a path: the skid-steer inverse kinematics of
a body twist at the wheel-speed stamps. A recorded command (cmd_vel) is held between messages and
rate-limited by the chain's reference slew, as the drive controllers received it; a measured twist
(an odometry's) is interpolated and used as it is."""

from __future__ import annotations

import numpy as np

from mrnc_eval.control.jit_cache import FloatArray
from mrnc_eval.control.kinematics import inverse_kinematics, slew


def wheel_speed_references(t: FloatArray, twist_t: FloatArray, v: FloatArray, omega: FloatArray, track_m: float, *,
                           held: bool, accel_limit_mps2: float = 0.0,
                           start: tuple[float, float] = (0.0, 0.0)) -> FloatArray:
    """(N, 2) left, right references (m/s) at the stamps t (s, inside [twist_t[0], twist_t[-1]])
    for the body twist v (m/s), omega (rad/s) stamped twist_t, track Lr (m). held: the last twist
    at or before each stamp (a command), slewed (m/s^2, <= 0 off) from `start` (the references
    before the recording began, m/s; the measured wheel speeds are the best guess); else linear
    interpolation (a measurement), not slewed."""
    if held:
        k = np.clip(np.searchsorted(twist_t, t, side="right") - 1, 0, twist_t.size - 1)
        v_t, w_t = v[k], omega[k]
    else:
        v_t, w_t = np.interp(t, twist_t, v), np.interp(t, twist_t, omega)
    out = np.empty((t.size, 2))
    left, right = start
    for i in range(t.size):
        target_l, target_r = inverse_kinematics(float(v_t[i]), float(w_t[i]), track_m)
        if held:
            dt = float(t[i] - t[i - 1]) if i else 0.0
            left, right = slew(left, target_l, accel_limit_mps2, dt), slew(right, target_r, accel_limit_mps2, dt)
        else:
            left, right = target_l, target_r
        out[i] = left, right
    return out
