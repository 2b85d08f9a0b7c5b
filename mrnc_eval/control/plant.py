"""Hydraulic in-wheel drive per side and skid-steer body motion (control-reference 4).

Per side, period dt: u_eff = deadband(u(k - d)); v_w <- a v_w + (1 - a) K (1 - s) u_eff with
a = exp(-dt / tau); the ground moves at (1 - s) v_w. On soft, wet patches (slip s > 0) the
drive loses speed under load (gain K (1 - s), a disturbance the wheel loop must reject) and
the body moves slower than the wheels turn (so wheel odometry drifts). Body: v = (vgL + vgR)/2,
omega = (vgR - vgL) / (chi Lr).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mrnc_eval.control.jit_cache import FloatArray, kernel


@dataclass(frozen=True)
class SlipPatch:
    x: float
    y: float
    radius_m: float
    slip: float


def patches_array(patches: list[SlipPatch]) -> FloatArray:
    return np.asarray([[p.x, p.y, p.radius_m, p.slip] for p in patches], dtype=np.float64).reshape(-1, 4)


@kernel
def slip_at(x: float, y: float, patches: FloatArray) -> float:
    s = 0.0
    for k in range(patches.shape[0]):
        if (x - patches[k, 0]) ** 2 + (y - patches[k, 1]) ** 2 <= patches[k, 2] ** 2:
            s = max(s, patches[k, 3])
    return s


@kernel
def dead_band(u: float, width: float) -> float:
    if u > width:
        return u - width
    if u < -width:
        return u + width
    return 0.0


@kernel
def leaky_gain(gain: float, leakage_at_limit: float, u: float, u_max: float) -> float:
    """Drive gain under pressure-dependent leakage: K (1 - leakage_at_limit min(|u| / u_max, 1)),
    (m/s)/RPM. With no leakage this is `gain` exactly (the default plant)."""
    if leakage_at_limit == 0.0:
        return gain
    return gain * (1.0 - leakage_at_limit * min(abs(u) / u_max, 1.0))


@kernel
def drive_step(v_wheel: float, u_delayed: float, slip: float, gain: float, a: float, dz: float) -> float:
    """Wheel surface speed (m/s) after one period."""
    return a * v_wheel + (1.0 - a) * gain * (1.0 - slip) * dead_band(u_delayed, dz)


@kernel
def body_step(x: float, y: float, yaw: float, vg_left: float, vg_right: float, track_eff: float,
              dt: float) -> tuple[float, float, float, float, float]:
    """Pose (x m, y m, yaw rad) after dt s on the ground speeds of both sides (m/s), and (v m/s, omega rad/s)."""
    x, y, yaw, v, w, _, _ = body_step_trig(x, y, yaw, math.cos(yaw), math.sin(yaw), vg_left, vg_right, track_eff, dt)
    return x, y, yaw, v, w


@kernel
def body_step_trig(x: float, y: float, yaw: float, cos_yaw: float, sin_yaw: float, vg_left: float, vg_right: float,
                   track_eff: float, dt: float) -> tuple[float, float, float, float, float, float, float]:
    """body_step given cos and sin of yaw, also returning those of the new yaw: the closed loop carries
    them from step to step (bit-identical: the new yaw is the same float as yaw + w dt), which saves
    four of six trigonometric calls per control period."""
    v = 0.5 * (vg_left + vg_right)
    w = (vg_right - vg_left) / track_eff
    # exact integration of a constant-twist arc over dt
    if abs(w) < 1e-9:
        x += v * dt * cos_yaw
        y += v * dt * sin_yaw
        yaw += w * dt
        return x, y, yaw, v, w, math.cos(yaw), math.sin(yaw)
    yaw_new = yaw + w * dt
    sin_new, cos_new = math.sin(yaw_new), math.cos(yaw_new)
    x += v / w * (sin_new - sin_yaw)
    y -= v / w * (cos_new - cos_yaw)
    return x, y, yaw_new, v, w, cos_new, sin_new
