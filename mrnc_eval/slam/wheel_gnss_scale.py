"""The wheel odometry's scale from GNSS, where the LiDAR cannot give it.

The online calibration takes the wheels' scale from distance steps the LiDAR odometry pinned
(wheel_calibration.fit_scale); on bare ground scan-to-map leaves x and y free and the scale stays at
its prior, so a rolling-radius error of 1.5 % (0.6 m along a 40 m line) went unnamed. Here, after the
run, the calibrated wheel track (yaw from the calibrated wheels and the gyro) is fitted to the fixes
by a 2-D similarity (yaw, translation, scale): fixes = k R wheels + t, so the wheels' scale is 1 / k.
Multipath jumps (0.5-3 m for seconds) are first taken out by the GNSS track's filter when one is given
(the multipath hypotheses, slam/gnss_bank.py: each fix replaced by the filter's position at its stamp;
on the open line's float logs the scale's sigma 1.4-3.0 % -> 0.2-0.8 %), then cut by a robust refit
(fixes beyond 3 robust sigmas plus 0.3 m of the fit); the standard error is a delete-one-block
jackknife over time blocks (the fixes' errors are correlated for seconds, so the formal one would be
too small), at least the fixes' own sigma with one independent error per correlation time: on a
small drive float errors stay correlated longer than a block (the open loop's U, 6 m RMS spread, 0.3 m
float fixes: a jackknife of -4.8 +- 1.5 % against a true +0.5 %). A constant GNSS latency
shifts every fix along the track by the same distance and leaves the scale; a wheel heading error
bends the track and is what the jackknife's spread then carries."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrnc_eval.data import GnssSeries
from mrnc_eval.slam.gnss_bank import OffsetBank
from mrnc_eval.slam.gnss_track import TrackFilter
from mrnc_eval.slam.jackknife import jackknife_sigma
from mrnc_eval.slam.wheel_odometry import WheelTrack

OUTLIER_SIGMAS = 3.0  # a fix this many robust sigmas (plus OUTLIER_FLOOR_M) off the fit is multipath
OUTLIER_FLOOR_M = 0.3
JACKKNIFE_BLOCKS = 10


@dataclass(frozen=True, kw_only=True)
class GnssScale:
    scale: float  # 1 + s: the wheels' distance over the fixes' (1.02: the wheels over-read by 2 %)
    sigma: float  # its 1-sigma (block jackknife)
    fixes: int  # fixes in the fit (multipath outliers left out)
    span_m: float  # RMS distance of those fixes from their centroid, m


def gnss_scale(wheel: WheelTrack, gnss: GnssSeries, *, max_var_m2: float, min_span_m: float,
               correlation_s: float = 0.0, track: TrackFilter | OffsetBank | None = None) -> GnssScale | None:
    """The wheels' scale against the usable fixes (horizontal variance at most max_var_m2, m^2) inside
    the wheel track's time span, through `track` (a fresh GNSS track filter) when given; None when
    fewer than 20 fixes or their spread (RMS from the centroid) is under min_span_m (m): the scale is
    not observable. The sigma is at least what the fixes' own sigmas give with one independent
    error per `correlation_s` (s; 0: every fix independent): a jackknife over 40 s cannot see errors
    correlated for longer than its blocks."""
    var = np.diagonal(gnss.covariance, axis1=1, axis2=2)[:, :2]
    use = np.all(np.isfinite(gnss.enu[:, :2]), axis=1) & np.all(var <= max_var_m2, axis=1) \
        & (gnss.stamps >= wheel.stamps[0]) & (gnss.stamps <= wheel.stamps[-1])
    if use.sum() < 20:
        return None
    t, fixes = gnss.stamps[use], gnss.enu[use, :2]
    if track is not None:
        fixes = _filtered(track, t, fixes, np.sqrt(np.max(var[use], axis=1)))
    wheels = np.column_stack([np.interp(t, wheel.stamps, wheel.positions[:, i]) for i in range(2)])
    keep = _robust_inliers(wheels, fixes)
    spread = float(np.sum((wheels[keep] - wheels[keep].mean(axis=0)) ** 2))  # m^2, summed over the fixes kept
    span = float(np.sqrt(spread / max(int(keep.sum()), 1)))
    if keep.sum() < 20 or span < min_span_m or span <= 0:
        return None
    k = _similarity_scale(wheels[keep], fixes[keep])
    blocks = np.array_split(np.flatnonzero(keep), JACKKNIFE_BLOCKS)
    loo = np.array([_similarity_scale(np.delete(wheels, b, axis=0)[np.delete(keep, b)],
                                      np.delete(fixes, b, axis=0)[np.delete(keep, b)]) for b in blocks])
    independent = max(1.0, float(t[keep][-1] - t[keep][0]) / correlation_s) if correlation_s > 0 else keep.sum()
    floor = float(np.median(np.sqrt(var[use][keep].max(axis=1)))) * np.sqrt(keep.sum() / independent / spread)
    sigma_k = max(jackknife_sigma(loo), float(floor))
    return GnssScale(scale=1.0 / k, sigma=sigma_k / k ** 2, fixes=int(keep.sum()), span_m=span)


def _filtered(track: TrackFilter | OffsetBank, t: np.ndarray, fixes: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Each fix (n, 2) replaced by the filter's position at its stamp once the filter has taken it."""
    out = np.empty_like(fixes)
    for k in range(t.size):
        track.update(float(t[k]), fixes[k], float(sigma[k]))
        out[k] = track.predict(float(t[k]))[0][:2]
    return out


def _robust_inliers(wheels: np.ndarray, fixes: np.ndarray) -> np.ndarray:
    """The fixes within OUTLIER_SIGMAS robust sigmas (+ OUTLIER_FLOOR_M) of the similarity fit, refitted
    on them until the set settles (at most 10 rounds)."""
    keep = np.ones(len(fixes), bool)
    for _ in range(10):
        res = np.linalg.norm(fixes - _similarity_apply(wheels[keep], fixes[keep], wheels), axis=1)
        sigma = 1.4826 * float(np.median(res[keep]))
        new = res <= OUTLIER_SIGMAS * sigma + OUTLIER_FLOOR_M
        if new.sum() < 20 or np.array_equal(new, keep):
            break
        keep = new
    return keep


def _similarity(x: np.ndarray, y: np.ndarray) -> tuple[complex, complex]:
    """y = a x + b in the complex plane (a = k e^{i yaw}), least squares, for (n, 2) points x, y."""
    zx, zy = x[:, 0] + 1j * x[:, 1], y[:, 0] + 1j * y[:, 1]
    mx, my = zx.mean(), zy.mean()
    a = complex(np.sum(np.conj(zx - mx) * (zy - my)) / np.sum(np.abs(zx - mx) ** 2))
    return a, complex(my - a * mx)


def _similarity_scale(x: np.ndarray, y: np.ndarray) -> float:
    return float(abs(_similarity(x, y)[0]))


def _similarity_apply(x_fit: np.ndarray, y_fit: np.ndarray, x: np.ndarray) -> np.ndarray:
    a, b = _similarity(x_fit, y_fit)
    z = a * (x[:, 0] + 1j * x[:, 1]) + b
    return np.column_stack([z.real, z.imag])
