"""FOPTC stand-in: prescribed-time time-varying gain (Song, Wang, Holloway & Krstic 2017).

The paper's FOPTC (Ge, Xu & Song 2023) was not available. Practical form, restarted at each
reference step (control-reference 3): t_s = min(t - t_seg, T - delta),
g = k0 + c h / (T - t_s) (1/s), I += ki e dt, u_fb = (tau_hat / K_hat) (g e + I) RPM with
e = v_ref - v (m/s), K_hat the assumed drive gain ((m/s)/RPM) and tau_hat its time constant.
Anti-windup (not part of the source law, on by default): conditional integration, i.e. the
integral is frozen while the total command is clamped and the error pushes further into
the clamp; without it the integral winds up against the 1250 RPM limit.
"""

from __future__ import annotations

from mrnc_eval.control.config import ControlConfig
from mrnc_eval.control.jit_cache import FloatArray, kernel, pack_slots


@kernel
def foptc_step(state: FloatArray, k0: float, c_h: float, horizon: float, freeze: float, ki: float, tau_hat: float,
               k_hat: float, anti_windup: bool, t_seg: float, err: float, u_ff: float, u_min: float, u_max: float,
               dt: float) -> float:
    """state = [integral m/s]. t_seg: time since the segment (reference step) started, s."""
    ts = min(t_seg, horizon - freeze)
    g = k0 + c_h / (horizon - ts)
    scale = tau_hat / k_hat
    integral = state[0] + ki * err * dt
    held: float = state[0]
    u_fb: float = scale * (g * err + integral)
    total = u_ff + u_fb
    if anti_windup and ((total > u_max and err > 0.0) or (total < u_min and err < 0.0)):
        return scale * (g * err + held)  # clamped and pushing further: hold the integral
    state[0] = integral
    return u_fb


# slots of the FOPTC parameters after the common head of the controller vector (controllers.P_LAW)
(FOPTC_K0, FOPTC_C_H, FOPTC_HORIZON, FOPTC_FREEZE, FOPTC_KI, FOPTC_TAU_HAT, FOPTC_K_HAT,
 FOPTC_ANTI_WINDUP) = range(8)


def foptc_params(cfg: ControlConfig) -> list[float]:
    c = cfg.foptc
    return pack_slots({FOPTC_K0: c.k0, FOPTC_C_H: c.c_h, FOPTC_HORIZON: c.horizon_s, FOPTC_FREEZE: c.freeze_before_s,
                       FOPTC_KI: c.ki, FOPTC_TAU_HAT: c.tau_hat_s, FOPTC_K_HAT: c.k_hat,
                       FOPTC_ANTI_WINDUP: 1.0 if c.anti_windup else 0.0})
