"""APC stand-in: Hou's CFDL model-free adaptive predictive control (CFDL-MFAPC).

The paper's APC (Zhu & Zhu 2024) was not available; control-reference 3 gives the
textbook law used here, rescaled to RPM (u_n = U / rpm_per_unit) and run at its own slow
rate with the command held in between (a one-step pseudo partial derivative cannot see
through the 40 ms drive delay at 1 kHz). At update k, with y the measured side speed (m/s):
  PPD:  phi(k) = phi(k-1) + eta dU(k-1) [dy(k) - phi(k-1) dU(k-1)] / (mu + dU(k-1)^2),
        reset to phi(1) if |phi| <= eps, |dU(k-1)| <= eps or its sign flips;
  AR(3) model of the PPD: theta += Phi [phi(k) - Phi^T theta] / (delta + |Phi|^2),
        Phi = [phi(k-1), phi(k-2), phi(k-3)], reset theta = (1, 0, 0) if |theta| >= M;
        phi(k+1) = theta^T [phi(k), phi(k-1), phi(k-2)] (same resets);
  move: A (N_p x 2) lower-triangular, column 0 = phi(k) in every row, column 1 = phi(k+1)
        from row 1 on (N_u = 2); dU = rho e1^T (A^T A + lambda I)^-1 A^T (Y* - y 1),
        Y* = the current reference held over the horizon (future references are unknown
        to a causal controller), first move only.
The shared feed-forward f = 3000 v_ref is added at the control rate; the MFAPC part is
the held increment on top, and the PPD is estimated from the total command.
"""

from __future__ import annotations

import math

from mrnc_eval.control.config import ControlConfig
from mrnc_eval.control.jit_cache import FloatArray, kernel, pack_slots

# law state slots
_PHI, _U_PREV, _Y_PREV, _DU_PREV, _INIT, _PHI_1, _PHI_2, _TH0, _TH1, _TH2, _FB = range(11)


@kernel
def _ppd_reset(phi: float, phi1: float, eps: float) -> float:
    if abs(phi) <= eps or phi * phi1 < 0.0 or not math.isfinite(phi):
        return phi1
    return phi


@kernel
def mfapc_step(state: FloatArray, phi1: float, eta: float, mu: float, rho: float, lam: float, eps: float, unit: float,
               n_pred: float, delta_ar: float, theta_max: float, v_ref: float, y: float, u_ff: float, u_min: float,
               u_max: float) -> float:
    """One MFAPC update. Returns the held feedback part (RPM) to add to the feed-forward u_ff."""
    ff = u_ff / unit
    if state[_INIT] == 0.0:
        state[_PHI], state[_PHI_1], state[_PHI_2] = phi1, phi1, phi1
        state[_U_PREV], state[_Y_PREV], state[_DU_PREV], state[_FB] = ff, y, 0.0, 0.0
        state[_TH0], state[_TH1], state[_TH2] = 1.0, 0.0, 0.0
        state[_INIT] = 1.0
    du = state[_DU_PREV]
    phi_old = state[_PHI]
    dy = y - state[_Y_PREV]
    phi = phi_old + eta * du * (dy - phi_old * du) / (mu + du * du)
    phi = phi1 if abs(du) <= eps else _ppd_reset(phi, phi1, eps)
    # AR(3) model of the PPD sequence, then the one-step prediction
    r0, r1, r2 = phi_old, state[_PHI_1], state[_PHI_2]
    pred = state[_TH0] * r0 + state[_TH1] * r1 + state[_TH2] * r2
    g = (phi - pred) / (delta_ar + r0 * r0 + r1 * r1 + r2 * r2)
    th0, th1, th2 = state[_TH0] + g * r0, state[_TH1] + g * r1, state[_TH2] + g * r2
    if math.sqrt(th0 * th0 + th1 * th1 + th2 * th2) >= theta_max:
        th0, th1, th2 = 1.0, 0.0, 0.0
    state[_TH0], state[_TH1], state[_TH2] = th0, th1, th2
    state[_PHI_2], state[_PHI_1], state[_PHI] = r1, r0, phi
    phi_next = _ppd_reset(th0 * phi + th1 * r0 + th2 * r1, phi1, eps)
    # first move of the N_u = 2 horizon: closed-form 2 x 2 solve
    err = v_ref - y
    m00 = n_pred * phi * phi + lam
    m01 = (n_pred - 1) * phi * phi_next
    m11 = (n_pred - 1) * phi_next * phi_next + lam
    b0 = n_pred * phi * err
    b1 = (n_pred - 1) * phi_next * err
    move = rho * (m11 * b0 - m01 * b1) / (m00 * m11 - m01 * m01)
    total = min(max(ff + state[_FB] + move, u_min / unit), u_max / unit)
    state[_FB] = total - ff
    state[_DU_PREV] = total - state[_U_PREV]
    state[_U_PREV] = total
    state[_Y_PREV] = y
    fb: float = state[_FB]
    return fb * unit


# slots of the MFAPC parameters after the common head of the controller vector (controllers.P_LAW)
(APC_PHI1, APC_ETA, APC_MU, APC_RHO, APC_LAM, APC_EPS, APC_UNIT, APC_N_PRED, APC_AR_DELTA, APC_AR_THETA_MAX,
 APC_PERIOD) = range(11)


def apc_params(cfg: ControlConfig) -> list[float]:
    c = cfg.apc
    return pack_slots({APC_PHI1: c.phi1, APC_ETA: c.eta, APC_MU: c.mu, APC_RHO: c.rho, APC_LAM: c.lam,
                       APC_EPS: c.eps, APC_UNIT: c.rpm_per_unit, APC_N_PRED: c.n_pred, APC_AR_DELTA: c.ar_delta,
                       APC_AR_THETA_MAX: c.ar_theta_max, APC_PERIOD: 1.0 / c.rate_hz})
