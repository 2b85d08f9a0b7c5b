"""Skid-steer inverse kinematics: v_R = v + omega Lr / 2, v_L = v - omega Lr / 2 (REP-103)."""

from __future__ import annotations

from mrnc_eval.control.jit_cache import kernel


@kernel
def inverse_kinematics(v: float, omega: float, track: float) -> tuple[float, float]:
    """(v_left, v_right) in m/s for body speed v (m/s), yaw rate omega (rad/s), track Lr (m)."""
    half = 0.5 * omega * track
    return v - half, v + half


@kernel
def slew(previous: float, target: float, max_rate: float, dt: float) -> float:
    """Rate-limit a reference (max_rate in units per second; <= 0 disables)."""
    if max_rate <= 0.0:
        return target
    step = max_rate * dt
    return previous + min(max(target - previous, -step), step)
