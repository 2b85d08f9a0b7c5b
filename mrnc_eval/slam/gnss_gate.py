"""GNSS that never makes the online estimate worse: a factor enters only when the fixes disagree
with the chain, judged on the fixes' own residuals, not on the chain's covariance (which wheel and
LiDAR factors of a centimetre make far too small once the chain drifts).

At each keyframe: the ENU -> map alignment (yaw + translation) is re-fitted on every fix so far
against the chain's antenna positions (keyframe poses interpolated at the fix stamps), so the rigid
part of the disagreement goes into the alignment and never slides the chain; the fixes of the last
`residual_window_s` give residuals, a robust line through them (offset now + drift rate) drops the
fixes far from it (multipath jumps), and when the offset now is significant (the chain drifted) a
GNSS factor at the keyframe pulls it by that offset, with its sigma and a Huber kernel; a
significant drift rate is the chain's velocity error (graph #2 restarts with it removed)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrnc_eval.data import GnssSeries
from mrnc_eval.geometry.point_fit import yaw_align
from mrnc_eval.slam.config import GpsConfig


@dataclass(frozen=True, kw_only=True)
class GateDecision:
    """What the gate found at one keyframe; `position` (map, m) and `variance` (m^2) when a factor enters."""

    residual_m: np.ndarray  # (2,) median residual of the window, map frame
    sigma_m: float  # its sigma
    inliers: int
    outliers: int
    position: np.ndarray | None = None
    variance: np.ndarray | None = None
    velocity_error: np.ndarray | None = None  # (2,) m/s, fixes minus chain, when significant


def antenna_track(kf_stamps: np.ndarray, kf_poses: np.ndarray, lever: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(len(t), 3) antenna positions (map) at the stamps t, linear between keyframes (clamped)."""
    ant = kf_poses[:, :3, :3] @ lever + kf_poses[:, :3, 3]
    return np.column_stack([np.interp(t, kf_stamps, ant[:, i]) for i in range(3)])


def fit_alignment(enu_xy: np.ndarray, map_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """2x2 rotation and translation with R enu + t ~ map, refitted once without the pairs whose
    residual exceeds 3x the median (multipath)."""
    def fit(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r, t = yaw_align(np.c_[a, np.zeros(len(a))], np.c_[b, np.zeros(len(b))])
        return r[:2, :2], t[:2]

    rot, t = fit(enu_xy, map_xy)
    res = np.linalg.norm(enu_xy @ rot.T + t - map_xy, axis=1)
    keep = res <= 3.0 * max(float(np.median(res)), 1e-3)
    if keep.sum() >= 3 and not keep.all():
        rot, t = fit(enu_xy[keep], map_xy[keep])
    return rot, t


def gate(gnss: GnssSeries, usable: np.ndarray, kf_stamps: np.ndarray, kf_poses: np.ndarray, lever: np.ndarray,
         cfg: GpsConfig, chain_sigma_m: float | None = None) -> tuple[GateDecision | None,
                                                                     tuple[np.ndarray, np.ndarray] | None]:
    """The decision at the newest keyframe and the alignment used (None before align_min_travel_m).
    `chain_sigma_m`: how far the chain can really have drifted since the last factor (1 sigma, m;
    None = unbounded): an offset beyond chi-square of it and the offset's own sigma is rejected."""
    t_now = float(kf_stamps[-1])
    sel = usable & (gnss.stamps >= kf_stamps[0]) & (gnss.stamps <= t_now)
    if sel.sum() < 3:
        return None, None
    ant = antenna_track(kf_stamps, kf_poses, lever, gnss.stamps[sel])
    if np.linalg.norm(ant[-1, :2] - ant[0, :2]) < cfg.align_min_travel_m:
        return None, None
    enu = gnss.enu[sel, :2]
    travel = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(ant[:, :2], axis=0), axis=1))]
    early = travel <= cfg.align_max_travel_m if cfg.align_max_travel_m > 0 else np.ones(travel.size, bool)
    rot, t = fit_alignment(enu[early], ant[early, :2])
    recent = gnss.stamps[sel] >= t_now - cfg.residual_window_s
    res = (enu[recent] @ rot.T + t) - ant[recent, :2]
    sig = np.sqrt(np.max(np.diagonal(gnss.covariance[sel][recent], axis1=1, axis2=2)[:, :2], axis=1))
    if res.shape[0] == 0:
        return None, (rot, t)
    # with wheels the chain is smooth over the window, so the residuals' scatter is the fixes'; without,
    # a chain dead-reckoning on bare ground bends away and its own curvature would pass for it
    fit = _robust_line(gnss.stamps[sel][recent] - t_now, res, sig, cfg, scatter_floor=chain_sigma_m is not None)
    if fit is None:
        return GateDecision(residual_m=np.zeros(2), sigma_m=float("inf"), inliers=0, outliers=int(recent.sum())), \
            (rot, t)
    med, sigma, velocity, inl = fit
    n = int(inl.sum())
    decision = GateDecision(residual_m=med, sigma_m=sigma, inliers=n, outliers=int((~inl).sum()))
    size = float(np.linalg.norm(med))
    if size < max(cfg.residual_drift_sigmas * sigma, cfg.residual_min_correction_m):
        return decision, (rot, t)
    if chain_sigma_m is not None and size ** 2 > cfg.residual_gate_chi2 * (sigma ** 2 + chain_sigma_m ** 2):
        return decision, (rot, t)  # more than the chain can have drifted: multipath held over the window
    ant_now = kf_poses[-1, :3, :3] @ lever + kf_poses[-1, :3, 3]
    position = np.r_[ant_now[:2] + med, ant_now[2]]
    return GateDecision(residual_m=med, sigma_m=sigma, inliers=n, outliers=decision.outliers, position=position,
                        variance=np.array([sigma ** 2, sigma ** 2, 0.01]), velocity_error=velocity), (rot, t)


def _robust_line(dt: np.ndarray, res: np.ndarray, sig: np.ndarray, cfg: GpsConfig, *, scatter_floor: bool = True
                 ) -> tuple[np.ndarray, float, np.ndarray | None, np.ndarray] | None:
    """A robust line per axis through the residuals, res = a + b dt (dt <= 0, s): the offset now
    (a, m), its sigma, the drift rate (b, m/s; None when not significant) and the inlier mask;
    fixes far from the line are outliers (multipath jumps). None with too few inliers or too
    short a span."""
    # The fixes' real scatter: a receiver in multipath keeps claiming centimetres while its fixes
    # wander by decimetres for seconds. As a per-axis sigma (the median distance of 2-D Gaussian
    # scatter is 1.1774 sigma), first about the window's median (a jump over a third of it does not
    # move that) to bound the claimed sigma in the outlier test.
    claimed = float(np.median(sig)) if sig.size else 0.0
    if scatter_floor and dt.size:
        sig = np.maximum(sig, float(np.median(np.linalg.norm(res - np.median(res, axis=0), axis=1))) / 1.1774)
    inl = np.ones(dt.size, bool)
    for _ in range(2):
        if inl.sum() < cfg.residual_min_fixes:
            break
        coef = _line_fit(dt[inl], res[inl])
        off = np.linalg.norm(res - (coef[0] + np.outer(dt, coef[1])), axis=1)
        inl = off <= cfg.residual_outlier_sigmas * sig + cfg.residual_floor_m
    n = int(inl.sum())
    if n < cfg.residual_min_fixes or np.ptp(dt[inl]) < 0.5 * cfg.residual_window_s:
        return None
    coef = _line_fit(dt[inl], res[inl])
    x = np.c_[np.ones(n), dt[inl]]
    cov = np.linalg.inv(x.T @ x) * float(np.median(sig[inl])) ** 2
    sigma = float(np.hypot(np.sqrt(cov[0, 0]), cfg.residual_floor_m))
    if scatter_floor:  # then the inliers' scatter about their line (a drifting chain is a line, not
        # scatter): above the claim, the errors are not white, so averaging the fixes does not shrink them
        scatter = float(np.median(np.linalg.norm(res[inl] - (coef[0] + np.outer(dt[inl], coef[1])), axis=1))) / 1.1774
        sigma = max(sigma, scatter if scatter > claimed else 0.0)
    slope_ok = np.linalg.norm(coef[1]) > cfg.residual_drift_sigmas * float(np.sqrt(cov[1, 1]))
    return coef[0], sigma, (coef[1] if slope_ok else None), inl


def _line_fit(dt: np.ndarray, res: np.ndarray) -> np.ndarray:
    """(2, 2): rows intercept and slope of res (n, 2) against dt (n,), least squares."""
    x = np.c_[np.ones(dt.size), dt]
    return np.asarray(np.linalg.lstsq(x, res, rcond=None)[0], float)
