"""Constant clock offset between an estimate and its reference (`--offset auto`).

Two steps, both independent of the frames the trajectories are expressed in:
1. coarse: the angular speed |w(t)| and the linear speed |v(t)| of each trajectory do not
   change under a rigid (or similarity) transform of either, so the lag that best
   correlates the estimate's speeds with the reference's is the offset to a sample or so;
2. fine: around that lag, the offset that minimises the APE (translation RMSE after
   SE(3), or Sim(3), alignment) with the reference interpolated at the shifted stamps;
   this is smooth in the offset, so a bounded scalar search converges to ~0.1 ms.
The offset is added to the estimate's stamps (the sign of `--offset`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.data import Trajectory
from mrnc_eval.errors import EvaluationError
from mrnc_eval.evaluation.align import align_positions, estimate_alignment
from mrnc_eval.evaluation.modes import AlignMode
from mrnc_eval.evaluation.sync import take
from mrnc_eval.geometry import lie
from mrnc_eval.geometry.interpolate import interpolate_at, sorted_unique
from mrnc_eval.peaks import parabola_vertex

MAX_SIGNAL_SAMPLES = 50_000  # the correlation grid is coarsened beyond this
MAX_REFINE_POSES = 20_000  # estimate poses used by the fine search (evenly spread)
MIN_CORRELATION = 0.3  # below this the speeds share no motion to lock on: refuse rather than guess


@dataclass(frozen=True)
class OffsetEstimate:
    offset_s: float  # added to the estimate's stamps
    coarse_s: float  # the correlation peak
    correlation: float  # Pearson correlation of the speed signals at the peak
    rmse_m: float  # aligned APE RMSE at offset_s (translation, m)


BASELINE_S = 0.25  # speeds are differences over this long (at least 3 poses): pose noise averages out


def _speeds(traj: Trajectory) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Mid-interval stamps, angular speed (rad/s) and linear speed (m/s) over a baseline of
    BASELINE_S (or 3 poses): consecutive differences of noisy poses are mostly noise."""
    t = traj.stamps
    baseline = max(BASELINE_S, 3.0 * float(np.median(np.diff(t))))
    i = np.arange(t.size)
    j = np.searchsorted(t, t + baseline, side="left")
    ok = j < t.size
    i, j = i[ok], j[ok]
    if i.size < 10:
        raise EvaluationError(f"--offset auto: trajectory {traj.name!r} is shorter than a few {baseline:.2f} s "
                              "baselines")
    r = lie.rotations(traj)
    dt = t[j] - t[i]
    turn = lie.rotation_angle(np.matmul(lie.transpose(r[i]), r[j]))
    move = np.linalg.norm(traj.positions[j] - traj.positions[i], axis=1)
    return (t[i] + t[j]) / 2, turn / dt, move / dt


def _zscore(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Zero mean, unit spread; a signal that is constant up to rounding carries nothing."""
    sd, mean = float(np.std(x)), float(np.mean(x))
    if sd <= 1e-9 * max(abs(mean), 1e-12):
        return np.zeros_like(x)
    out: NDArray[np.float64] = (x - mean) / sd
    return out


def _correlation_by_lag(ref: Trajectory, est: Trajectory, lags: NDArray[np.float64],
                        step: float) -> NDArray[np.float64]:
    """Mean of the angular- and linear-speed correlations at each lag (NaN: no overlap)."""
    t_ref, w_ref, v_ref = _speeds(ref)
    t_est, w_est, v_est = _speeds(est)
    grid = np.arange(t_est[0], t_est[-1], step)
    if grid.size > MAX_SIGNAL_SAMPLES:
        grid = np.linspace(t_est[0], t_est[-1], MAX_SIGNAL_SAMPLES)
    signals = [(np.interp(grid, t_est, w_est), t_ref, w_ref), (np.interp(grid, t_est, v_est), t_ref, v_ref)]
    out = np.full(lags.size, np.nan)
    for k, lag in enumerate(lags):
        shifted = grid + lag
        inside = (shifted >= t_ref[0]) & (shifted <= t_ref[-1])
        if inside.sum() < 10:
            continue
        corr = [float(np.mean(_zscore(b[inside]) * _zscore(np.interp(shifted[inside], tr, a))))
                for b, tr, a in signals]
        out[k] = float(np.mean(corr))
    return out


def _aligned_rmse(ref: Trajectory, est: Trajectory, offset: float, max_gap: float, align: AlignMode) -> float:
    ref_i, idx = interpolate_at(ref, est.stamps + offset, max_gap)
    if idx.size < 10:
        return float("inf")
    est_m = take(est, idx)
    a = estimate_alignment(ref_i, est_m, align)
    d = align_positions(est_m.positions, a) - ref_i.positions
    return float(np.sqrt(np.mean(np.einsum("ij,ij->i", d, d))))


def estimate_offset(ref: Trajectory, est: Trajectory, *, max_offset: float = 1.0,
                    align: AlignMode | str = AlignMode.se3) -> OffsetEstimate:
    """The constant offset (s, added to the estimate's stamps) within +-max_offset."""
    from scipy.optimize import minimize_scalar

    ref, est = sorted_unique(ref), sorted_unique(est)
    if len(ref) < 10 or len(est) < 10:
        raise EvaluationError("--offset auto needs at least 10 poses in each trajectory")
    align = AlignMode.sim3 if AlignMode(align) in (AlignMode.sim3, AlignMode.scale) else AlignMode.se3
    step = 0.5 * float(min(np.median(np.diff(ref.stamps)), np.median(np.diff(est.stamps))))
    step = max(step, 2.0 * max_offset / 2000)  # at most ~2000 lags
    lags = np.arange(-max_offset, max_offset + step / 2, step)
    corr = _correlation_by_lag(ref, est, lags, step)
    if np.all(np.isnan(corr)):
        raise EvaluationError(f"--offset auto: the trajectories do not overlap in time within +-{max_offset} s")
    peak = int(np.nanargmax(corr))
    if corr[peak] < MIN_CORRELATION:
        raise EvaluationError(f"--offset auto: the speeds of {est.name or 'the estimate'} and the reference do not "
                              f"correlate (best {corr[peak]:.2f} within +-{max_offset} s): no shared motion to "
                              "estimate a clock offset from; give --offset in seconds")
    coarse = float(lags[peak])
    if 0 < peak < lags.size - 1 and np.all(np.isfinite(corr[peak - 1:peak + 2])):
        coarse += float(parabola_vertex(*corr[peak - 1:peak + 2])) * step
    if len(est) > MAX_REFINE_POSES:
        est = take(est, np.linspace(0, len(est) - 1, MAX_REFINE_POSES).astype(np.int64))
    max_gap = 5.0 * float(np.median(np.diff(ref.stamps)))

    def cost(d: float) -> float:
        return _aligned_rmse(ref, est, d, max_gap, align)

    # scan the APE a few samples around the peak (the correlation can be off by one or two
    # samples on noisy poses), then a bounded search in the best cell
    window = max(6.0 * step, 0.1)
    grid = np.arange(coarse - window, coarse + window + step / 4, step / 2)
    best = float(grid[int(np.argmin([cost(float(d)) for d in grid]))])
    fine = minimize_scalar(cost, bounds=(best - step / 2, best + step / 2), method="bounded",
                           options={"xatol": 1e-5})
    offset = float(fine.x)
    return OffsetEstimate(offset_s=offset, coarse_s=coarse, correlation=float(corr[peak]), rmse_m=float(fine.fun))
