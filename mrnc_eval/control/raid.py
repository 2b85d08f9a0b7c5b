"""The paper's RAID wheel-speed law (paper-notes 4.1-4.6).

Per side i, with e = v - v_ref (m/s; the paper's sign) and the funnel
o(t) = (o_ov - o_b) exp(-o* t) + o_b (m/s; t in s, o* in 1/s):
  u_fb = -beta e / 2 - odot^2 e^3 / (o^2 (o^2 - e^2))
         - e / (o^2 - e^2) (phi^4 ||Phi|| + ||Phi||^2 + vdot_ref^2 + 1)          (law units)
  phi_dot = -kappa phi / 2 + (e / (o^2 - e^2))^2 phi^3 ||Phi||                     (1/s)
  Phi_k(v) = exp(-(v - alpha_k)^2 / gamma^2), alpha = 2 rand - 1 (seeded), k = 1..N
The pump command is f + scale * u_fb with the feed-forward f = 3000 v_ref RPM (the -f_i of
the printed law cancels the +f_i of U = lambda (u + f) + lambda_bar; paper-notes 4.2); the
safety clamp follows in controllers.py. phi is integrated with explicit Euler at the
control period. At or beyond the barrier (|e| >= o) or on a non-finite value the law
reports failure: the caller records a safety stop and commands zero (paper-notes 4.5).
"""

from __future__ import annotations

import math

import numpy as np

from mrnc_eval.control.config import ControlConfig
from mrnc_eval.control.jit_cache import FloatArray, kernel, pack_slots


@kernel
def funnel(t: float, o_ov: float, o_b: float, o_star: float) -> tuple[float, float]:
    """o(t) (m/s) and do/dt (m/s^2) for t >= 0 in seconds and o* in 1/s. The one funnel of the
    package: the closed loop calls it per sample, a replay with an array of t (see funnel_series)."""
    ex = (o_ov - o_b) * np.exp(-o_star * t)
    return ex + o_b, -o_star * ex


@kernel
def rbf_norms(v: float, centres: FloatArray, gamma: float) -> tuple[float, float]:
    """(||Phi(v)||, ||Phi(v)||^2) of the Gaussian RBF layer."""
    norm2 = 0.0
    for k in range(centres.size):
        g = math.exp(-((v - centres[k]) ** 2) / (gamma * gamma))
        norm2 += g * g
    return math.sqrt(norm2), norm2


@kernel
def raid_step(state: FloatArray, centres: FloatArray, gamma: float, beta: float, kappa: float, scale: float,
              e: float, o: float, odot: float, vdot_ref: float, v_meas: float, dt: float) -> tuple[float, bool]:
    """RAID feedback in RPM (scale RPM per law unit). state[0] = phi, advanced by one period.
    Returns (u_fb, ok); ok is False at or beyond the barrier or on non-finite values
    (then phi is left unchanged and u_fb = 0)."""
    gap = o * o - e * e
    if not (gap > 0.0) or not math.isfinite(e):
        return 0.0, False
    phi = state[0]
    norm, norm2 = rbf_norms(v_meas, centres, gamma)
    u = (-0.5 * beta * e - odot * odot * e ** 3 / (o * o * gap)
         - e / gap * (phi ** 4 * norm + norm2 + vdot_ref * vdot_ref + 1.0))
    phi_new = phi + dt * (-0.5 * kappa * phi + (e / gap) ** 2 * phi ** 3 * norm)
    u *= scale
    if not (math.isfinite(u) and math.isfinite(phi_new)):
        return 0.0, False
    state[0] = phi_new
    return u, True


def funnel_series(t: FloatArray, cfg: ControlConfig) -> FloatArray:
    """o(t) in m/s at the times t (s after the anchor) by the configured funnel."""
    f = cfg.funnel
    o, _ = funnel(np.asarray(t, dtype=np.float64), f.o_ov_mps, f.o_b_mps, f.o_star_per_s)  # type: ignore[arg-type]
    return np.asarray(o, dtype=np.float64)


# slots of RAID's parameters after the common head of the controller vector (controllers.P_LAW)
RAID_GAMMA, RAID_BETA, RAID_KAPPA, RAID_SCALE, RAID_PHI0 = range(5)


def raid_params(cfg: ControlConfig) -> list[float]:
    r = cfg.raid
    return pack_slots({RAID_GAMMA: r.gamma, RAID_BETA: r.beta, RAID_KAPPA: r.kappa, RAID_SCALE: r.feedback_scale_rpm,
                       RAID_PHI0: r.phi0})


def rbf_centres(cfg: ControlConfig) -> FloatArray:
    """alpha = 2 rand - 1 (uniform in [-1, 1] m/s), seeded with raid.centre_seed (printed in reports)."""
    return 2.0 * np.random.default_rng(cfg.raid.centre_seed).random(cfg.raid.n_neurons) - 1.0
