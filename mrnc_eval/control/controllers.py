"""Per-side wheel-speed controllers with one step interface.

Each law is a compiled kernel `*_step(state, params, t, v_ref, vdot_ref, v_meas, dt, ...)`
returning the feedback command (RPM) added to the feed-forward f = 3000 v_ref; the
closed-loop engine calls the kernels, and the small classes below wrap them for use
from Python (replay, tests). Errors: RAID uses e = v - v_ref (paper); the baselines use
r - y. Stand-ins for the paper's APC and FOPTC are labelled as such everywhere.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from mrnc_eval.control.config import ControlConfig

CONTROLLERS = ("raid", "pid", "apc", "foptc")
LABELS = {
    "raid": "RAID",
    "pid": "PID",
    "apc": "APC (stand-in: CFDL-MFAC)",
    "foptc": "FOPTC (stand-in: prescribed-time gain)",
}
CONTROLLER_ID = {name: k for k, name in enumerate(CONTROLLERS)}


@njit(cache=True)
def funnel(t: float, o_ov: float, o_b: float, o_star: float) -> tuple[float, float]:
    """o(t) = (o_ov - o_b) exp(-o* t) + o_b and its time derivative (m/s, m/s^2)."""
    ex = (o_ov - o_b) * math.exp(-o_star * t)
    return ex + o_b, -o_star * ex


@njit(cache=True)
def raid_step(state, centres, gamma, beta, kappa, scale, e, o, odot, vdot_ref, v_meas, dt):
    """RAID feedback (paper eq. u_i without -f_i, which is the feed-forward). state[0] = phi.
    Returns (u_fb RPM, ok); ok is False at or beyond the barrier or on non-finite values."""
    gap = o * o - e * e
    if not (gap > 0.0) or not math.isfinite(e):
        return 0.0, False
    phi = state[0]
    norm2 = 0.0
    for k in range(centres.size):
        g = math.exp(-((v_meas - centres[k]) ** 2) / (gamma * gamma))
        norm2 += g * g
    norm = math.sqrt(norm2)
    u = (-0.5 * beta * e - odot * odot * e ** 3 / (o * o * gap)
         - e / gap * (phi ** 4 * norm + norm2 + vdot_ref * vdot_ref + 1.0))
    dphi = -0.5 * kappa * phi + (e / gap) ** 2 * phi ** 3 * norm
    phi_new = phi + dphi * dt
    u *= scale
    if not (math.isfinite(u) and math.isfinite(phi_new)):
        return 0.0, False
    state[0] = phi_new
    return u, True


@njit(cache=True)
def pid_step(state, kp, ki, kd, mode, tt, err, u_ff, u_min, u_max, dt):
    """PID on err = r - y with anti-windup. state = [integral, previous error, initialised].
    mode: 0 back-calculation, 1 conditional integration, 2 none. Returns u_fb (RPM)."""
    if state[2] == 0.0:
        state[1] = err
        state[2] = 1.0
    deriv = (err - state[1]) / dt
    state[1] = err
    u_unsat = kp * err + state[0] + kd * deriv
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


@njit(cache=True)
def mfac_step(state, phi1, eta, mu, rho, lam, eps, unit, y_ref_next, y, u_min, u_max, u_ff):
    """CFDL-MFAC (Hou) in normalised units u_n = U / unit, called at its own (slow) rate.
    state = [phi_hat, u_prev, y_prev, du_prev, initialised]. Returns the total command (RPM)."""
    if state[4] == 0.0:
        state[0], state[1], state[2], state[3], state[4] = phi1, u_ff / unit, y, 0.0, 1.0
    dy = y - state[2]
    du = state[3]
    phi = state[0] + eta * du * (dy - state[0] * du) / (mu + du * du)
    if abs(phi) <= eps or abs(du) <= eps or phi * phi1 < 0.0:
        phi = phi1
    u = state[1] + rho * phi * (y_ref_next - y) / (lam + phi * phi)
    u = min(max(u, u_min / unit), u_max / unit)
    state[0], state[3], state[1], state[2] = phi, u - state[1], u, y
    return u * unit


@njit(cache=True)
def foptc_step(state, k0, c_h, horizon, freeze, ki, tau_hat, k_hat, t_seg, err, dt):
    """Prescribed-time time-varying gain g = k0 + c h / (T - t_s), t_s frozen at T - delta,
    restarted at each reference step; PI-like with the gain. state = [integral]. Returns u_fb."""
    ts = min(t_seg, horizon - freeze)
    g = k0 + c_h / (horizon - ts)
    state[0] += ki * err * dt
    return (tau_hat / k_hat) * (g * err + state[0])


# parameter vector layout shared by the Python wrapper and the closed-loop engine
P_FF, P_UMAX, P_SATFB, P_STEP, P_ANCHOR, P_OOV, P_OB, P_OSTAR = range(8)
P_LAW = 8  # law-specific parameters start here


def controller_params(name: str, cfg: ControlConfig) -> np.ndarray:
    """Pack the configuration of one law into a float vector for the compiled kernels."""
    a, f = cfg.actuator, cfg.funnel
    common = [a.feedforward_rpm_per_mps, a.u_max_rpm, 1.0 if a.saturation_applies_to == "feedback" else 0.0,
              cfg.metrics.step_threshold_mps, 1.0 if f.anchor == "reference_change" else 0.0,
              f.o_ov_mps, f.o_b_mps, f.o_star_per_s]
    if name == "raid":
        r = cfg.raid
        law = [r.gamma, r.beta, r.kappa, r.feedback_scale_rpm, r.phi0]
    elif name == "pid":
        p = cfg.pid
        law = [p.kp, p.ki, p.kd, {"back_calculation": 0, "conditional": 1, "none": 2}[p.anti_windup], p.tracking_time_s]
    elif name == "apc":
        c = cfg.apc
        law = [c.phi1, c.eta, c.mu, c.rho, c.lam, c.eps, c.rpm_per_unit, 1.0 / c.rate_hz]
    elif name == "foptc":
        c = cfg.foptc
        law = [c.k0, c.c_h, c.horizon_s, c.freeze_before_s, c.ki, c.tau_hat_s, c.k_hat]
    else:
        raise ValueError(f"unknown controller {name!r}; choose from {', '.join(CONTROLLERS)}")
    return np.asarray(common + law, dtype=np.float64)


STATE_SIZE = 10  # per side: law state [0..4], segment start, last reference, held command, next update, init


@njit(cache=True)
def controller_step(cid, state, p, centres, t, v_ref, vdot_ref, v_meas, dt):
    """One control period of law `cid` for one side: (total pump command RPM, ok).
    ok is False on a RAID safety stop (barrier reached or non-finite), then the command is 0."""
    u_ff = p[P_FF] * v_ref
    u_max = p[P_UMAX]
    if state[9] == 0.0 or abs(v_ref - state[6]) > p[P_STEP]:
        state[5] = t  # a reference step starts a segment
    if state[9] == 0.0:
        if cid == 0:
            state[0] = p[P_LAW + 4]  # phi(0)
        state[9] = 1.0
    state[6] = v_ref
    total = u_ff
    if cid == 0:
        t0 = state[5] if p[P_ANCHOR] > 0.5 else 0.0
        o, odot = funnel(t - t0, p[P_OOV], p[P_OB], p[P_OSTAR])
        u_fb, ok = raid_step(state, centres, p[P_LAW], p[P_LAW + 1], p[P_LAW + 2], p[P_LAW + 3],
                             v_meas - v_ref, o, odot, vdot_ref, v_meas, dt)
        if not ok:
            return 0.0, False
        total = u_ff + u_fb
    elif cid == 1:
        total = u_ff + pid_step(state, p[P_LAW], p[P_LAW + 1], p[P_LAW + 2], int(p[P_LAW + 3]), p[P_LAW + 4],
                                v_ref - v_meas, u_ff, -u_max, u_max, dt)
    elif cid == 2:
        if t >= state[8] - 1e-12:
            state[7] = mfac_step(state, p[P_LAW], p[P_LAW + 1], p[P_LAW + 2], p[P_LAW + 3], p[P_LAW + 4],
                                 p[P_LAW + 5], p[P_LAW + 6], v_ref, v_meas, -u_max, u_max, u_ff)
            state[8] = t + p[P_LAW + 7]
        total = state[7]
    else:
        total = u_ff + foptc_step(state, p[P_LAW], p[P_LAW + 1], p[P_LAW + 2], p[P_LAW + 3], p[P_LAW + 4],
                                  p[P_LAW + 5], p[P_LAW + 6], t - state[5], v_ref - v_meas, dt)
    if p[P_SATFB] > 0.5:
        return u_ff + min(max(total - u_ff, -u_max), u_max), True
    return min(max(total, -u_max), u_max), True


class WheelController:
    """One side, one law: `step(t, v_ref, vdot_ref, v_meas, dt) -> (pump command RPM, ok)`."""

    def __init__(self, name: str, cfg: ControlConfig) -> None:
        self.name = name
        self.label = LABELS[name]
        self.params = controller_params(name, cfg)
        self.centres = rbf_centres(cfg)
        self.state = np.zeros(STATE_SIZE)

    def step(self, t: float, v_ref: float, vdot_ref: float, v_meas: float, dt: float) -> tuple[float, bool]:
        return controller_step(CONTROLLER_ID[self.name], self.state, self.params, self.centres,
                               t, v_ref, vdot_ref, v_meas, dt)


def rbf_centres(cfg: ControlConfig) -> np.ndarray:
    """alpha = 2 rand - 1 (uniform in [-1, 1]), seeded (the seed is printed in reports)."""
    return 2.0 * np.random.default_rng(cfg.raid.centre_seed).random(cfg.raid.n_neurons) - 1.0
