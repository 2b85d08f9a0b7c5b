"""LiDAR-IMU time offset from the run itself: the rotation the LiDAR odometry saw between
consecutive mapped sweeps against the gyro integrated over the same interval shifted by a
candidate offset. The offset is positive when the IMU stamps are late (an IMU sample stamped
t was measured at t - offset)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrnc_eval.geometry import rotation
from mrnc_eval.peaks import parabola_vertex
from mrnc_eval.slam.imu import ImuTrack
from mrnc_eval.slam.jackknife import equal_share_blocks, jackknife_sigma

SEARCH_S = 0.1  # offsets searched in [-SEARCH_S, SEARCH_S], s
MAX_INTERVAL_S = 0.3  # median spacing of the mapped sweeps above which rates are too smoothed to time
STEP_S = 5e-4  # grid step before the parabolic refinement, s
GRID_S = np.arange(-SEARCH_S, SEARCH_S + STEP_S / 2, STEP_S)  # the candidate offsets, s
RATE_SMOOTH_S = 0.05  # the gyro averaged over +-this when the information per interval is weighed, s


def lidar_angular_rates(stamps: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """(N-1, 3) mean body angular velocity (rad/s, LiDAR axes) between consecutive poses."""
    step = rotation.log(np.swapaxes(rotations[:-1], 1, 2) @ rotations[1:])
    return np.asarray(step / np.diff(stamps)[:, None], np.float64)


def _gyro_integral(track: ImuTrack) -> tuple[np.ndarray, np.ndarray]:
    """Cumulative integral of the gyro at the track stamps, rad, with the track's own hold (each
    sample constant to the next track stamp; see imu.imu_track for how samples are centred)."""
    dt = np.diff(track.stamps)
    return track.stamps, np.vstack([np.zeros(3), np.cumsum(track.gyro[:-1] * dt[:, None], axis=0)])


def _imu_rates(t_imu: np.ndarray, integral: np.ndarray, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
    """Mean gyro (rad/s) over each [t0, t1] from the integral (linear between samples)."""
    def at(t: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(t, t_imu, integral[:, a]) for a in range(3)])

    return np.asarray((at(t1) - at(t0)) / (t1 - t0)[:, None], np.float64)


def _axis_costs(offset: float, t0: np.ndarray, t1: np.ndarray, lidar: np.ndarray, t_imu: np.ndarray,
                integral: np.ndarray) -> np.ndarray:
    """(3,) mean squared rate difference per axis after removing the mean difference (a constant
    gyro bias)."""
    diff = _imu_rates(t_imu, integral, t0 + offset, t1 + offset) - lidar
    diff -= diff.mean(axis=0)
    return np.asarray(np.mean(diff * diff, axis=0), np.float64)


@dataclass(frozen=True, kw_only=True)
class OffsetEstimate:
    """An IMU-LiDAR time offset estimate with its standard error."""

    offset_s: float
    sigma_s: float  # formal standard error (residuals taken as independent: a lower bound), s
    intervals: int  # sweep intervals compared


def estimate_imu_time_offset(stamps: np.ndarray, rotations: np.ndarray, track: ImuTrack,
                             measured: np.ndarray | None = None, *, axis_weights: bool = True) -> float | None:
    """The offset (s) of `imu_time_offset`, or None."""
    est = imu_time_offset(stamps, rotations, track, measured, axis_weights=axis_weights)
    return None if est is None else est.offset_s


def imu_time_offset(stamps: np.ndarray, rotations: np.ndarray, track: ImuTrack,
                    measured: np.ndarray | None = None, *, axis_weights: bool = True) -> OffsetEstimate | None:
    """Offset (s) minimising the rate mismatch on a 0.5 ms grid within +/-0.1 s, refined by a
    parabola through the best grid point and its neighbours. None when fewer than 10 sweep
    intervals lie inside the IMU span, the mapped sweeps are more than MAX_INTERVAL_S apart (a
    throttled log: 1 s rotation increments do not time a few ms), or the motion has no rotation
    to correlate. `measured` (per sweep) marks poses the LiDAR determined (scan-to-map ran and was
    not degenerate): an interval counts only when both ends are, since a kept IMU guess would
    compare the gyro with itself. `axis_weights`: each axis's squared rate mismatch divided by its
    own smallest (False: summed as they are)."""
    inside = (stamps - SEARCH_S >= track.stamps[0]) & (stamps + SEARCH_S <= track.stamps[-1])
    ok = inside if measured is None else inside & np.asarray(measured, bool)
    spaced = stamps[inside] if inside.sum() >= 2 else stamps  # the mapped sweeps' spacing, where the IMU is
    if stamps.size < 2 or float(np.median(np.diff(spaced))) > MAX_INTERVAL_S:
        return None
    pair = ok[:-1] & ok[1:]
    if pair.sum() < 10:
        return None
    lidar = lidar_angular_rates(stamps, rotations)[pair]
    return offset_from_rates(stamps[:-1][pair], stamps[1:][pair], lidar, track, axis_weights=axis_weights)


def offset_from_rates(t0: np.ndarray, t1: np.ndarray, lidar: np.ndarray, track: ImuTrack, *,
                      axis_weights: bool = True) -> OffsetEstimate | None:
    """The offset fit of `imu_time_offset` on given intervals [t0, t1] (s) and the LiDAR's mean angular
    velocity over each (rad/s, LiDAR axes). None without rotation to correlate or under 10 intervals."""
    if t0.size < 10 or float(np.std(lidar, axis=0).max()) < 1e-3:  # rad/s: nothing to correlate
        return None
    t_imu, integral = _gyro_integral(track)
    per_axis = np.array([_axis_costs(o, t0, t1, lidar, t_imu, integral) for o in GRID_S])  # (G, 3)
    weighted = _axis_weighted(per_axis)
    offset, on_bound = _grid_minimum(weighted if axis_weights else per_axis.sum(axis=1))
    n = int(t0.size)
    if on_bound:
        return OffsetEstimate(offset_s=offset, sigma_s=float("inf"), intervals=n)
    # chi^2(o) = n * weighted(o) with each axis's noise its best mean square: sigma^2 = 2 / chi^2''
    kw = min(max(int(np.argmin(weighted)), 1), GRID_S.size - 2)
    curv = (weighted[kw - 1] - 2 * weighted[kw] + weighted[kw + 1]) / STEP_S ** 2
    sigma = float(np.sqrt(2.0 / (n * curv))) if curv > 0 else float("inf")
    return OffsetEstimate(offset_s=offset, sigma_s=sigma, intervals=n)


def _axis_weighted(per_axis: np.ndarray) -> np.ndarray:
    """(G,) cost from (G, 3) mean squares per candidate and axis: each axis divided by its own
    smallest (floored at 1e-3 of the largest such): the LiDAR times its axes unequally (a roll held
    by the ground alone scatters more), and an axis that scatters should not set the offset for the
    others (a maximum-likelihood fit with a noise level per axis)."""
    floor = max(float(per_axis.min(axis=0).max()) * 1e-3, 1e-12)
    return np.asarray(per_axis @ (1.0 / np.maximum(per_axis.min(axis=0), floor)), np.float64)


def _grid_minimum(cost: np.ndarray) -> tuple[float, bool]:
    """(the offset at the cost's minimum over GRID_S, refined by a parabola through it and its
    neighbours, s; whether it lies on the search bound, unrefined)."""
    k = int(np.argmin(cost))
    if k == 0 or k == GRID_S.size - 1:
        return float(GRID_S[k]), True
    return float(GRID_S[k] + parabola_vertex(cost[k - 1], cost[k], cost[k + 1]) * STEP_S), False


def _mismatches(t0: np.ndarray, t1: np.ndarray, lidar: np.ndarray, t_imu: np.ndarray,
                integral: np.ndarray) -> np.ndarray:
    """(G, N, 3) rate difference (gyro - LiDAR, rad/s) of every interval at every grid offset."""
    return np.stack([_imu_rates(t_imu, integral, t0 + o, t1 + o) - lidar for o in GRID_S])


def _information_blocks(t0: np.ndarray, t1: np.ndarray, mismatch: np.ndarray, t_imu: np.ndarray,
                        integral: np.ndarray, blocks: int) -> np.ndarray:
    """Block index per interval for the jackknife (`equal_share_blocks` in t0 order). An interval's
    information: the squared change of its gyro mean rate per second of offset (the rate at t1 minus at t0,
    over t1 - t0, each averaged over +-RATE_SMOOTH_S), per axis over that axis's `mismatch` variance (N, 3;
    at the estimate, the noise); `t_imu`, `integral` the gyro's (`_gyro_integral`)."""
    h = RATE_SMOOTH_S
    slope = (_imu_rates(t_imu, integral, t1 - h, t1 + h) - _imu_rates(t_imu, integral, t0 - h, t0 + h)) \
        / (t1 - t0)[:, None]  # rad/s per s of offset
    info = np.sum(slope * slope / np.maximum(np.var(mismatch, axis=0), 1e-12), axis=1)
    order = np.argsort(t0, kind="stable")
    block = np.empty(t0.size, np.int64)
    block[order] = equal_share_blocks(info[order], blocks)
    return block


def _offset_from_sums(s1: np.ndarray, s2: np.ndarray, n: np.ndarray) -> tuple[float, bool]:
    """The grid fit of `offset_from_rates` (each axis's mean square after removing its mean difference)
    from block sums: (offset s, on the search bound)."""
    total = float(n.sum())
    a, b = s1.sum(axis=1), s2.sum(axis=1)  # (G, 3)
    return _grid_minimum(_axis_weighted((b - a * a / total) / total))


def offset_from_overlapping(t0: np.ndarray, t1: np.ndarray, lidar: np.ndarray, track: ImuTrack, *,
                            blocks: int = 10) -> OffsetEstimate | None:
    """The fit of `offset_from_rates` on intervals that may share their ends (each pose in several
    intervals: their residuals are correlated, the formal error would be too small), with a
    delete-one-block jackknife standard error over `blocks` contiguous stretches of the log carrying equal
    shares of the information (`_information_blocks`). None under 10 intervals or without rotation; sigma
    inf when the estimate lies on the search bound."""
    if t0.size < max(10, blocks) or float(np.std(lidar, axis=0).max()) < 1e-3:
        return None
    t_imu, integral = _gyro_integral(track)
    diffs = _mismatches(t0, t1, lidar, t_imu, integral)
    found, on_bound = _offset_from_sums(diffs.sum(axis=1)[:, None], (diffs * diffs).sum(axis=1)[:, None],
                                        np.array([float(t0.size)]))
    if on_bound:
        return OffsetEstimate(offset_s=found, sigma_s=float("inf"), intervals=int(t0.size))
    block = _information_blocks(t0, t1, diffs[int(np.argmin(np.abs(GRID_S - found)))], t_imu, integral, blocks)
    order = np.argsort(block, kind="stable")
    starts = np.flatnonzero(np.diff(block[order], prepend=-1))  # the blocks that hold intervals
    ordered = diffs[:, order]
    s1 = np.add.reduceat(ordered, starts, axis=1)  # (G, B', 3)
    s2 = np.add.reduceat(ordered * ordered, starts, axis=1)
    n = np.diff(np.append(starts, t0.size)).astype(np.float64)
    reps = np.array([_offset_from_sums(np.delete(s1, b, axis=1), np.delete(s2, b, axis=1), np.delete(n, b))[0]
                     for b in range(n.size)])
    return OffsetEstimate(offset_s=found, sigma_s=jackknife_sigma(reps), intervals=int(t0.size))
