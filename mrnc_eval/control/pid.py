"""PID baseline with anti-windup (control-reference 3, ros-controls Pid semantics).

err = v_ref - v (m/s); u_fb = kp err + I + kd d(err)/dt (RPM) on top of the shared
feed-forward. Anti-windup against the +/-u_max clamp of the total command:
back-calculation I += dt (ki err + (u_sat - u) / T_t), conditional integration
(integrate only while unsaturated or when the error drives out of saturation), or none.
"""

from __future__ import annotations

from mrnc_eval.control.config import ControlConfig
from mrnc_eval.control.jit_cache import FloatArray, kernel, pack_slots

ANTI_WINDUP = {"back_calculation": 0, "conditional": 1, "none": 2}


@kernel
def pid_step(state: FloatArray, kp: float, ki: float, kd: float, mode: int, tt: float, err: float, u_ff: float,
             u_min: float, u_max: float, dt: float) -> float:
    """state = [integral RPM, previous error, initialised]. Returns u_fb (RPM)."""
    if state[2] == 0.0:
        state[1] = err
        state[2] = 1.0
    deriv = (err - state[1]) / dt
    state[1] = err
    u_unsat: float = kp * err + state[0] + kd * deriv
    total = u_ff + u_unsat
    sat = min(max(total, u_min), u_max)
    if mode == 0:
        state[0] += dt * (ki * err + (sat - total) / tt)
    elif mode == 1:
        if total == sat or err * u_unsat <= 0.0:
            state[0] += dt * ki * err
    else:
        state[0] += dt * ki * err
    return u_unsat


# slots of the PID parameters after the common head of the controller vector (controllers.P_LAW)
PID_KP, PID_KI, PID_KD, PID_MODE, PID_TT = range(5)


def pid_params(cfg: ControlConfig) -> list[float]:
    p = cfg.pid
    return pack_slots({PID_KP: p.kp, PID_KI: p.ki, PID_KD: p.kd, PID_MODE: ANTI_WINDUP[p.anti_windup],
                       PID_TT: p.tracking_time_s})
