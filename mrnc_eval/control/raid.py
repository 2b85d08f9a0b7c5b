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
              e: float, o: float, odot: float, vdot_ref: float, v_meas: float, dt: float,
              e_unit: float = 1.0) -> tuple[float, bool]:
    """RAID feedback in RPM (scale RPM per law unit). state[0] = phi, advanced by one period.
    e, o, odot are divided by e_unit (m/s) first (1: the law in m/s; o_b: normalised by the funnel
    floor). Returns (u_fb, ok); ok is False at or beyond the barrier or on non-finite values
    (then phi is left unchanged and u_fb = 0)."""
    if not (o * o - e * e > 0.0) or not math.isfinite(e):
        return 0.0, False
    e, o, odot = e / e_unit, o / e_unit, odot / e_unit
    gap = o * o - e * e
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
RAID_GAMMA, RAID_BETA, RAID_KAPPA, RAID_SCALE, RAID_PHI0, RAID_E_UNIT = range(6)


def output_units(cfg: ControlConfig) -> tuple[float, float]:
    """(RPM per law unit, error unit m/s) of the declared reading of RAID's output (raid.output_unit):
    rpm_per_unit: the law's output is RPM x feedback_scale_rpm, e in m/s (the literal reading);
    error_over_floor: e, o, do/dt in units of the funnel floor o_b, output RPM x feedback_scale_rpm;
    feedforward_gain: the output is a speed (m/s) turned into RPM by the feed-forward gain
    (3000 RPM per m/s) x feedback_scale_rpm."""
    r = cfg.raid
    if r.output_unit == "feedforward_gain":
        return r.feedback_scale_rpm * cfg.model.feedforward_rpm_per_mps, 1.0
    if r.output_unit == "error_over_floor":
        return r.feedback_scale_rpm, cfg.funnel.o_b_mps
    return r.feedback_scale_rpm, 1.0


def raid_params(cfg: ControlConfig) -> list[float]:
    r = cfg.raid
    rpm_per_unit, e_unit = output_units(cfg)
    return pack_slots({RAID_GAMMA: r.gamma, RAID_BETA: r.beta, RAID_KAPPA: r.kappa, RAID_SCALE: rpm_per_unit,
                       RAID_PHI0: r.phi0, RAID_E_UNIT: e_unit})


def interior_gain(cfg: ControlConfig, *, v: float, phi: float, o: float | None = None, vdot_ref: float = 0.0) -> float:
    """Linearised RAID gain d U / d e at e = 0, RPM per (m/s) of speed error: the loop gain of the law
    inside the funnel (the e^3 term has zero slope there). At speed v (m/s, the RBF input), adaptive
    parameter phi and funnel width o (default the floor o_b)."""
    rpm_per_unit, e_unit = output_units(cfg)
    o_n = (cfg.funnel.o_b_mps if o is None else o) / e_unit
    norm, norm2 = rbf_norms(v, rbf_centres(cfg), cfg.raid.gamma)
    return rpm_per_unit / e_unit * (0.5 * cfg.raid.beta + (phi ** 4 * norm + norm2 + vdot_ref ** 2 + 1.0) / o_n ** 2)


def rbf_centres(cfg: ControlConfig) -> FloatArray:
    """alpha = 2 rand - 1 (uniform in [-1, 1] m/s), seeded with raid.centre_seed (printed in reports)."""
    return 2.0 * np.random.default_rng(cfg.raid.centre_seed).random(cfg.raid.n_neurons) - 1.0


def local_gain(cfg: ControlConfig, *, e_over_o: float, v: float, phi: float, o: float | None = None) -> float:
    """-dU/de (RPM per m/s) of the RAID law at |e| = e_over_o * o (central difference; vdot_ref = 0):
    the gain grows without bound towards the barrier."""
    rpm_per_unit, e_unit = output_units(cfg)
    o_n = (cfg.funnel.o_b_mps if o is None else o) / e_unit
    norm, norm2 = rbf_norms(v, rbf_centres(cfg), cfg.raid.gamma)
    a = phi ** 4 * norm + norm2 + 1.0

    def law(e: float) -> float:
        gap = o_n * o_n - e * e
        return -(0.5 * cfg.raid.beta * e + e / gap * a)

    e0 = e_over_o * o_n
    h = 1e-6 * o_n
    return -rpm_per_unit / e_unit * (law(e0 + h) - law(e0 - h)) / (2 * h)


def e_over_o_at_gain(cfg: ControlConfig, gain_rpm_per_mps: float, *, v: float, phi: float) -> float:
    """|e|/o_b at which RAID's local gain reaches gain_rpm_per_mps (bisection; 0 if the interior gain
    already exceeds it)."""
    if local_gain(cfg, e_over_o=0.0, v=v, phi=phi) >= gain_rpm_per_mps:
        return 0.0
    lo, hi = 0.0, 1.0 - 1e-12
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if local_gain(cfg, e_over_o=mid, v=v, phi=phi) < gain_rpm_per_mps:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
