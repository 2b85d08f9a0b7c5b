"""ground_mount: the LiDAR mount's roll and pitch error seen from the ground at the start of a log.

A ground vehicle's base frame stands parallel to the ground under its wheels. The first sweeps'
ground around the machine (a ring, by default 2-8 m from the base origin), put into base axes
through the written /tf_static mount, is tilted by the mount's roll and pitch error when that ground
is the footprint's plane: a robust plane fit gives the tilt (true relative to written, base axes;
yaw is not observable from a plane). Whether the ring's plane *is* the footprint's is what decides
the uncertainty, so it carries three terms per axis: the fit's own standard error, the ground's
local slope spread at the footprint's scale (cell-mean heights `slope_baseline_m` apart, the cells'
noise removed) and the bend (the inner and the outer half of the ring tilted apart). A ground with
vegetation, a slope change or short waves (the simulated field terrain: 0.04 m at 2.7-3.7 m, slopes
of several degrees) gives a large sigma and the verdict "not measurable" instead of a wrong number."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mrnc_eval.geometry import rotation
from mrnc_eval.slam.config import GroundMountConfig

AXES = ("roll", "pitch")


@dataclass(kw_only=True)
class GroundMount:
    roll_deg: float  # mount roll error (true relative to written, base axes), deg
    pitch_deg: float  # mount pitch error, deg
    roll_sigma_deg: float  # fit, slope spread and bend together, deg
    pitch_sigma_deg: float
    points: int  # ring points inside the fit
    residual_m: float  # robust standard deviation of the heights about the plane, m
    inlier_fraction: float  # ring points within the fit's cut
    slope_spread_deg: tuple[float, float] = (float("nan"), float("nan"))  # roll, pitch axis
    bend_deg: tuple[float, float] = (float("nan"), float("nan"))  # inner minus outer half, roll, pitch
    # rotation to right-multiply the written mount's rotation by (roll, pitch, yaw, LiDAR axes, deg):
    # only the flagged axes; yaw stays 0
    correction_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    verdict: str = "not measurable"  # "ok", "misaligned" or "not measurable"
    reasons: list[str] = field(default_factory=list)
    sweeps: int = 0  # sweeps the points came from (set by the caller)
    cpu_ms: float = 0.0  # reading and fitting them (set by the caller)

    def as_dict(self) -> dict[str, object]:
        return {"roll_deg": self.roll_deg, "pitch_deg": self.pitch_deg, "roll_sigma_deg": self.roll_sigma_deg,
                "pitch_sigma_deg": self.pitch_sigma_deg, "points": self.points, "residual_m": self.residual_m,
                "inlier_fraction": self.inlier_fraction, "slope_spread_deg": list(self.slope_spread_deg),
                "bend_deg": list(self.bend_deg), "correction_rpy_deg": list(self.correction_rpy_deg),
                "verdict": self.verdict, "reasons": list(self.reasons), "sweeps": self.sweeps, "cpu_ms": self.cpu_ms}


def ground_mount(points: np.ndarray, mount_rotation: np.ndarray, cfg: GroundMountConfig, *,
                 sweep: np.ndarray | None = None) -> GroundMount:
    """The mount's roll and pitch error from (N, 3) points in the written base frame (m; the first
    sweeps through /tf_static's mount, the machine's body removed; `sweep`: each point's sweep, None
    = one); `mount_rotation`: the written base_link -> LiDAR rotation (3x3), for LiDAR axes."""
    p = np.asarray(points, float)
    rh = np.hypot(p[:, 0], p[:, 1])
    in_ring = (rh >= cfg.ring_m[0]) & (rh <= cfg.ring_m[1])
    ring = p[in_ring]
    labels = np.zeros(p.shape[0], int)[in_ring] if sweep is None else np.asarray(sweep)[in_ring]
    nan = float("nan")
    out = GroundMount(roll_deg=nan, pitch_deg=nan, roll_sigma_deg=nan, pitch_sigma_deg=nan, points=0,
                      residual_m=nan, inlier_fraction=0.0)
    if ring.shape[0] < cfg.min_points:
        out.reasons = [f"{ring.shape[0]} points in the {cfg.ring_m[0]:g}-{cfg.ring_m[1]:g} m ring: too few"]
        return out
    coef, sigma, inl = robust_plane(ring, cfg.max_residual_m)
    g = ring[inl]
    out.points, out.residual_m, out.inlier_fraction = int(g.shape[0]), sigma, float(inl.mean())
    tilt, fit_sd = _tilt(coef), _fit_sigma(g, sigma)
    out.roll_deg, out.pitch_deg = float(tilt[0]), float(tilt[1])
    spread, bend = slope_spread(g, cfg, labels[inl]), _bend(g, cfg)
    out.slope_spread_deg, out.bend_deg = (float(spread[0]), float(spread[1])), (float(bend[0]), float(bend[1]))
    total = np.sqrt(fit_sd ** 2 + spread ** 2 + bend ** 2)
    out.roll_sigma_deg, out.pitch_sigma_deg = float(total[0]), float(total[1])
    out.reasons = _unusable(out, cfg)
    if out.reasons:
        return out
    _judge(out, tilt, total, mount_rotation, cfg)
    return out


def _judge(out: GroundMount, tilt: np.ndarray, sigma: np.ndarray, mount_rotation: np.ndarray,
           cfg: GroundMountConfig) -> None:
    """Verdict, reasons and correction of a measurable ground: an axis within max_sigma_deg is read; it
    is flagged beyond flag_deg and flag_sigmas standard errors."""
    read = sigma <= cfg.max_sigma_deg
    if not read.any():
        out.reasons = [f"the ground is not the footprint's plane to {cfg.max_sigma_deg:g} deg (sigma roll "
                       f"{sigma[0]:.2f}, pitch {sigma[1]:.2f} deg: slope spread, bend)"]
        return
    flagged = read & (np.abs(tilt) > cfg.flag_deg) & (np.abs(tilt) > cfg.flag_sigmas * sigma)
    out.reasons = [f"{a} {t:+.2f} +- {s:.2f} deg" for a, t, s, f in zip(AXES, tilt, sigma, flagged, strict=True) if f]
    out.reasons += [f"{a} not measurable (sigma {s:.2f} deg)" for a, s, r in zip(AXES, sigma, read, strict=True)
                    if not r]
    out.verdict = "misaligned" if flagged.any() else "ok" if read.all() else "not measurable"
    w_base = np.radians([tilt[0] * flagged[0], tilt[1] * flagged[1], 0.0])
    corr = np.degrees(rotation.rpy(rotation.exp(np.asarray(mount_rotation, float).T @ w_base))) + 0.0  # no -0.0
    out.correction_rpy_deg = (float(corr[0]), float(corr[1]), float(corr[2]))


def _unusable(out: GroundMount, cfg: GroundMountConfig) -> list[str]:
    """Why the ring is no plane at all (vegetation, clutter, too few ground points), or nothing."""
    reasons = []
    if out.points < cfg.min_points:
        reasons.append(f"{out.points} ground points: too few")
    if out.residual_m > cfg.max_residual_m:
        reasons.append(f"heights scatter {out.residual_m:.3f} m about the plane (> {cfg.max_residual_m:g} m)")
    if out.inlier_fraction < cfg.min_inlier_fraction:
        reasons.append(f"{out.inlier_fraction:.0%} of the ring on the plane (< {cfg.min_inlier_fraction:.0%})")
    return reasons


def robust_plane(p: np.ndarray, max_residual_m: float, iterations: int = 8) -> tuple[np.ndarray, float, np.ndarray]:
    """z = c0 + c1 x + c2 y fitted to (N, 3) points, m: started on the lower half of the heights (the
    ground under walls, trunks, bushes), then refitted to the points within 3 robust sigma (floor
    max_residual_m / 3). Returns the coefficients, the robust sigma of the kept points (m) and the mask."""
    a = np.c_[np.ones(p.shape[0]), p[:, 0], p[:, 1]]
    keep = p[:, 2] <= _median(p[:, 2])
    coef, sigma = np.zeros(3), float("inf")
    for _ in range(iterations):
        coef = np.linalg.lstsq(a[keep], p[keep, 2], rcond=None)[0]
        r = p[:, 2] - a @ coef
        sigma = 1.4826 * _median(np.abs(r[keep]))
        keep = np.abs(r) <= 3.0 * max(sigma, max_residual_m / 3.0)
        if keep.sum() < 3:
            break
    return coef, sigma, keep


def _median(x: np.ndarray) -> float:
    """The (upper) median by partition: np.median's first call imports numpy.ma (~20 ms before the run)."""
    k = x.size // 2
    return float(np.partition(x, k)[k]) if x.size else float("nan")


def _tilt(coef: np.ndarray) -> np.ndarray:
    """(roll, pitch) mount error, deg, from the plane z = c0 + c1 x + c2 y in the written base frame: its
    normal (-c1, -c2, 1) is the base z axis turned back by the error w (n = z + z x w: w_x = -c2, w_y = c1)."""
    return np.degrees([np.arctan(-coef[2]), np.arctan(coef[1])])


def _fit_sigma(g: np.ndarray, sigma: float) -> np.ndarray:
    """Least-squares standard errors of the (roll, pitch) tilt, deg; neighbouring returns share the
    ground's texture, so the point count is taken as a hundredth of itself (a conservative floor)."""
    a = np.c_[np.ones(g.shape[0]), g[:, 0], g[:, 1]]
    try:
        cov = np.linalg.inv(a.T @ a) * sigma ** 2 * 100.0
    except np.linalg.LinAlgError:  # returns on one line (or one point): the plane's tilt is not determined
        return np.array([np.inf, np.inf])
    return np.degrees(np.sqrt([cov[2, 2], cov[1, 1]]))


def slope_spread(g: np.ndarray, cfg: GroundMountConfig, sweep: np.ndarray | None = None) -> np.ndarray:
    """RMS of the ground's local slope about a smooth bowl's, (across y: roll, along x: pitch) deg, from
    the mean height residuals of cells `cell_m` wide taken `slope_baseline_m` apart; each pair's noise
    (the cells' standard errors) is removed from the mean square. The bowl (a quadratic surface) takes
    out gentle relief: its curvature tilts the ring's sides against each other, yet a plane fitted over
    a ring around the base still has the slope at its centre. Per sweep (`sweep`: each point's sweep),
    mean squares averaged: a standing machine's sweeps repeat each pixel's range error (incidence,
    divergence), so copies of one return in a cell are not independent noise."""
    x, y = g[:, 0], g[:, 1]
    a = np.c_[np.ones_like(x), x, y, x * x, x * y, y * y]
    r = g[:, 2] - a @ np.linalg.lstsq(a, g[:, 2], rcond=None)[0]
    labels = np.zeros(g.shape[0], int) if sweep is None else np.asarray(sweep)
    # sweeps by bincount, not np.unique: its first call imports numpy.ma (~20 ms before the run)
    msq = np.array([_slope_msq(g[labels == k, :2], r[labels == k], cfg)
                    for k in np.flatnonzero(np.bincount(labels))]).reshape(-1, 2)
    # a sweep with too few cell pairs (a partial one; inf) says nothing, the others still do; none: inf
    said = np.isfinite(msq)
    mean = np.where(said.any(axis=0), np.where(said, msq, 0.0).sum(axis=0) / np.maximum(said.sum(axis=0), 1), np.inf)
    spread: np.ndarray = np.degrees(np.arctan(np.sqrt(np.maximum(mean, 0.0))))
    return spread


def _slope_msq(xy: np.ndarray, r: np.ndarray, cfg: GroundMountConfig) -> np.ndarray:
    """Noise-corrected mean square of the cell-mean height slopes of one sweep, (roll, pitch) axes,
    (m/m)^2; inf with fewer than 10 cell pairs."""
    half = int(np.ceil(cfg.ring_m[1] / cfg.cell_m))
    ij = np.clip(np.floor(xy / cfg.cell_m).astype(int) + half, 0, 2 * half - 1)
    n, s, s2 = (np.zeros((2 * half, 2 * half)) for _ in range(3))
    np.add.at(n, (ij[:, 0], ij[:, 1]), 1.0)
    np.add.at(s, (ij[:, 0], ij[:, 1]), r)
    np.add.at(s2, (ij[:, 0], ij[:, 1]), r * r)
    ok = n >= 3
    mean = np.where(ok, s / np.maximum(n, 1), np.nan)
    var_mean = np.where(ok, np.maximum(s2 / np.maximum(n, 1) - mean ** 2, 0.0) / np.maximum(n - 1, 1), np.nan)
    k = max(1, int(round(cfg.slope_baseline_m / cfg.cell_m)))
    base = k * cfg.cell_m
    out = []
    for axis in (1, 0):  # roll: slopes across (y, axis 1); pitch: along (x, axis 0)
        d = _shifted(mean, k, axis)
        v = _shifted(var_mean, k, axis, add=True)
        good = np.isfinite(d) & np.isfinite(v)
        out.append(float(np.mean((d[good] / base) ** 2 - v[good] / base ** 2)) if good.sum() >= 10 else np.inf)
    return np.array(out)


def _shifted(a: np.ndarray, k: int, axis: int, *, add: bool = False) -> np.ndarray:
    """a[i + k] - a[i] (or + with `add`) along `axis` of a 2-D grid."""
    lo = [slice(None), slice(None)]
    hi = [slice(None), slice(None)]
    lo[axis], hi[axis] = slice(None, -k), slice(k, None)
    out: np.ndarray = a[tuple(hi)] + a[tuple(lo)] if add else a[tuple(hi)] - a[tuple(lo)]
    return out


def _bend(g: np.ndarray, cfg: GroundMountConfig) -> np.ndarray:
    """|inner half's tilt - outer half's| of the ring, (roll, pitch) deg: a slope change or a curved ground."""
    rh = np.hypot(g[:, 0], g[:, 1])
    mid = 0.5 * (cfg.ring_m[0] + cfg.ring_m[1])
    parts = [g[rh < mid], g[rh >= mid]]
    if min(q.shape[0] for q in parts) < 3:
        return np.array([float("inf"), float("inf")])
    tilts = [_tilt(np.linalg.lstsq(np.c_[np.ones(q.shape[0]), q[:, :2]], q[:, 2], rcond=None)[0]) for q in parts]
    bend: np.ndarray = np.abs(tilts[0] - tilts[1])
    return bend
