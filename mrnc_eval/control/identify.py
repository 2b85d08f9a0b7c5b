"""The drive identified from a log (issue 25 item 9): per side gain K ((m/s)/RPM), dead band dz (RPM),
time constant tau (s) and transport delay d (s) of the model the simulation uses
(control-reference 4): v <- a v + (1 - a) K deadband(u(t - d)), a = exp(-dt / tau), from the recorded
pump commands (held between messages) and wheel speeds.

Output-error fit: the model is simulated from the first measured speed over the whole record and
(K, tau, dz) minimise the squared difference to the measured speed (unbiased under white measurement
noise, unlike an equation-error fit on noisy regressors), for each delay on a grid; the delay is the
grid minimum refined to 1 ms. Uncertainty (1 sigma): from the Jacobian at the optimum,
sigma^2 (J^T J)^-1, and for the delay from the curvature of the squared error over the delay profile.
Slip lowers the apparent gain (the wheel turns slower under load): identify on dry ground or read K
as K (1 - mean slip).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from mrnc_eval.control.jit_cache import FloatArray, kernel


class IdentificationError(ValueError):
    """The record cannot identify the drive (too short, no excitation, no commands)."""


@dataclass(frozen=True, kw_only=True)
class DriveEstimate:
    gain_mps_per_rpm: float
    gain_sd: float
    dead_band_rpm: float
    dead_band_sd: float
    tau_s: float
    tau_sd: float
    delay_s: float
    delay_sd: float
    rms_residual_mps: float  # of the simulated speed against the measured one
    samples: int


@kernel
def simulate_drive(v0: float, a: FloatArray, x: FloatArray) -> FloatArray:
    """v[0] = v0, v[k+1] = a[k] v[k] + (1 - a[k]) x[k] (x = K deadband(u) per interval, m/s)."""
    v = np.empty(x.size + 1)
    v[0] = v0
    for k in range(x.size):
        v[k + 1] = a[k] * v[k] + (1.0 - a[k]) * x[k]
    return v


def held_means(stamps: FloatArray, values: FloatArray, t0: FloatArray, t1: FloatArray,
               signal: str = "held") -> FloatArray:
    """Mean over [t0, t1] (s) of the command: held from each stamp to the next ("held": what a pump
    does with its command messages), or linearly interpolated between stamps ("sampled": a faster
    command recorded at a lower rate, as the simulator's logs are). Before the first stamp the first
    value, after the last the last."""
    dts = np.diff(stamps)
    if signal == "sampled":
        slopes = np.diff(values) / np.maximum(dts, 1e-12)
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (values[:-1] + values[1:]) * dts)])
    else:
        slopes = np.zeros(dts.size)
        cum = np.concatenate([[0.0], np.cumsum(values[:-1] * dts)])
    slopes = np.append(slopes, 0.0)

    def integral(t: FloatArray) -> FloatArray:
        j = np.clip(np.searchsorted(stamps, t, side="right") - 1, 0, stamps.size - 1)
        h = t - stamps[j]
        return np.asarray(cum[j] + values[j] * h + 0.5 * slopes[j] * np.where(h > 0, h, 0.0) ** 2)

    width = np.maximum(t1 - t0, 1e-12)
    return np.asarray((integral(t1) - integral(t0)) / width)


def _dead_band(u: FloatArray, dz: float) -> FloatArray:
    return np.asarray(np.sign(u) * np.maximum(np.abs(u) - dz, 0.0))


def _fit_at_delay(t: FloatArray, v: FloatArray, cmd_t: FloatArray, cmd_u: FloatArray, delay: float,
                  start: NDArray[np.float64], signal: str) -> tuple[NDArray[np.float64], float, NDArray[np.float64]]:
    """(K, tau, dz), squared error and Jacobian of the output-error fit at one delay; K is fitted in
    units of 1/3000 (m/s)/RPM so the parameters have similar magnitudes."""
    dt = np.diff(t)
    u_bar = held_means(cmd_t, cmd_u, t[:-1] - delay, t[1:] - delay, signal)

    def residual(p: NDArray[np.float64]) -> NDArray[np.float64]:
        k, tau, dz = p[0] / 3000.0, p[1], p[2]
        a = np.exp(-dt / tau)
        return np.asarray(simulate_drive(float(v[0]), a, k * _dead_band(u_bar, dz))[1:] - v[1:])

    fit = least_squares(residual, start, bounds=([1e-3, 0.01, 0.0], [10.0, 5.0, 800.0]), x_scale=[0.1, 0.1, 20.0])
    return fit.x, float(np.sum(fit.fun ** 2)), fit.jac


def identify_side(t: FloatArray, v: FloatArray, cmd_t: FloatArray, cmd_u: FloatArray, *,
                  max_delay_s: float = 0.2, coarse_step_s: float = 0.01, signal: str = "held") -> DriveEstimate:
    """Identify one side from wheel speeds v (m/s) at t (s) and pump commands cmd_u (RPM) at cmd_t
    (`signal`: how the command runs between its stamps, see held_means)."""
    order = np.argsort(t)
    t, v = np.asarray(t, float)[order], np.asarray(v, float)[order]
    c_order = np.argsort(cmd_t)
    cmd_t, cmd_u = np.asarray(cmd_t, float)[c_order], np.asarray(cmd_u, float)[c_order]
    keep = t >= cmd_t[0] + max_delay_s  # every sample has a command max_delay_s before it
    t, v = t[keep], v[keep]
    if t.size < 50:
        raise IdentificationError(f"{t.size} wheel-speed samples after the first command: need at least 50")
    if np.ptp(cmd_u) < 100.0 or np.ptp(v) < 0.05:
        raise IdentificationError("the commands or the speeds hardly change (less than 100 RPM or 0.05 m/s): "
                                  "a step or a start-up is needed to see gain, lag and delay")
    moving = np.abs(cmd_u) > 1.0
    k0 = float(np.median(np.abs(v[v != 0]))) / max(float(np.median(np.abs(cmd_u[moving]))), 1.0) * 3000.0
    start = np.array([min(max(k0, 0.05), 5.0), 0.3, 30.0])
    delays = np.arange(0.0, max_delay_s + 1e-12, coarse_step_s)
    sse = np.empty(delays.size)
    params: list[NDArray[np.float64]] = []
    for i, d in enumerate(delays):
        p, sse[i], _ = _fit_at_delay(t, v, cmd_t, cmd_u, float(d), start, signal)
        params.append(p)
        start = p
    best = int(np.argmin(sse))
    fine = np.arange(max(0.0, delays[best] - coarse_step_s), delays[best] + coarse_step_s + 1e-12, 0.001)
    fine_sse, fine_fit = [], []
    for d in fine:
        p, s, jac = _fit_at_delay(t, v, cmd_t, cmd_u, float(d), params[best], signal)
        fine_sse.append(s)
        fine_fit.append((p, jac))
    j = int(np.argmin(fine_sse))
    p, jac = fine_fit[j]
    n = t.size - 1
    sigma2 = fine_sse[j] / max(n - 4, 1)
    try:
        cov = sigma2 * np.linalg.inv(jac.T @ jac)
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        sd = np.full(3, np.inf)
    return DriveEstimate(gain_mps_per_rpm=float(p[0]) / 3000.0, gain_sd=float(sd[0]) / 3000.0,
                         dead_band_rpm=float(p[2]),
                         dead_band_sd=float(sd[2]), tau_s=float(p[1]), tau_sd=float(sd[1]),
                         delay_s=float(fine[j]), delay_sd=_delay_sd(fine, np.asarray(fine_sse), j, sigma2),
                         rms_residual_mps=math.sqrt(fine_sse[j] / n), samples=n)


def _delay_sd(d: FloatArray, sse: FloatArray, j: int, sigma2: float) -> float:
    """1-sigma of the delay from the curvature of the squared error at its minimum: the squared error
    rises by 2 sigma^2 ... (profile: sd = sqrt(2 sigma^2 / SSE''))); at least half the grid step."""
    step = float(d[1] - d[0]) if d.size > 1 else 0.001
    if 0 < j < d.size - 1:
        curv = (sse[j - 1] - 2 * sse[j] + sse[j + 1]) / step ** 2
        if curv > 0:
            return max(math.sqrt(2.0 * sigma2 / curv), 0.5 * step)
    return step
