"""Association of two trajectories by time stamp, with evo's semantics.

For each stamp of the shorter trajectory (the estimate on equal length), the closest
stamp of the longer one within `max_diff` is taken; bounds are inclusive and ties go to
the earlier stamp. Matches need not be one-to-one. `offset` is added to the estimate's
clock (applied, as in evo, to the longer trajectory's stamps).

Files are taken as they are, like evo: repeated stamps are matched like any others and the
input order is kept. When the longer trajectory's stamps are not sorted, evo falls back to
a per-stamp search of the whole trajectory (first index of the smallest difference); so do
we, in O(n log n). `strict` refuses repeated or unsorted stamps instead.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.data import Trajectory
from mrnc_eval.errors import EvaluationError
from mrnc_eval.evaluation.modes import SyncMethod
from mrnc_eval.geometry.interpolate import interpolate_at, sorted_unique


@dataclass(frozen=True)
class Matches:
    """Index pairs of reference and estimate poses associated by time."""

    ref_idx: NDArray[np.int64]
    est_idx: NDArray[np.int64]


@dataclass(frozen=True)
class StampCounts:
    """How far a trajectory's stamps are from strictly increasing."""

    repeated: int  # stamps equal to an earlier stamp
    unsorted: int  # steps back in time (t[i] < t[i - 1])

    def summary(self) -> dict[str, int]:
        return {"repeated": self.repeated, "unsorted": self.unsorted}


def stamp_counts(stamps: NDArray[np.float64]) -> StampCounts:
    # Neighbours compared, not np.diff: the same answers for finite stamps, 1 byte a stamp, not 8
    unsorted = int(np.count_nonzero(stamps[1:] < stamps[:-1]))
    if unsorted == 0:  # the common case: no sort needed
        return StampCounts(int(np.count_nonzero(stamps[1:] == stamps[:-1])), 0)
    ordered = np.sort(stamps)
    return StampCounts(int(np.count_nonzero(ordered[1:] == ordered[:-1])), unsorted)


def distinct_count(idx: NDArray[np.int64]) -> int:
    """How many different indices (sorted ones need no sort)."""
    if np.all(idx[1:] >= idx[:-1]):
        return int(idx.size - np.count_nonzero(idx[1:] == idx[:-1]))
    ordered = np.sort(idx)
    return int(np.count_nonzero(ordered[1:] != ordered[:-1]) + (idx.size > 0))


def label_of(traj: Trajectory, role: str) -> str:
    return f"{role} trajectory {traj.name!r}" if traj.name else f"{role} trajectory"


def check_trajectory(traj: Trajectory, role: str, *, strict: bool = False) -> StampCounts:
    """Reject what would make association meaningless; count repeated and unsorted stamps
    (refused when `strict`)."""
    label = label_of(traj, role)
    if len(traj) < 2:
        raise EvaluationError(f"{label} has {len(traj)} pose(s); at least 2 are needed")
    if not (np.isfinite(traj.stamps).all() and np.isfinite(traj.positions).all() and np.isfinite(traj.quat_xyzw).all()):
        raise EvaluationError(f"{label} contains NaN or infinite values")
    counts = stamp_counts(traj.stamps)
    if strict and counts.repeated:
        raise EvaluationError(f"{label} has {counts.repeated} duplicate time stamp(s); remove them before "
                              "evaluating (or drop --strict to pair them as evo does)")
    if strict and counts.unsorted:
        raise EvaluationError(f"{label} has {counts.unsorted} time stamp(s) earlier than the one before; sort the "
                              "file before evaluating (or drop --strict to pair them as evo does)")
    return counts


BLOCK = 1 << 16  # short stamps per block: each is matched on its own, blocks bound the temporaries (~3 MB)


def _nearest_within(long_t: NDArray[np.float64], short_t: NDArray[np.float64],
                    max_diff: float) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(short indices, long indices) of accepted matches; long_t non-decreasing. Block by block
    into two index arrays of the short length (trimmed views): no list of parts to concatenate."""
    short_out = np.empty(short_t.size, dtype=np.int64)
    long_out = np.empty(short_t.size, dtype=np.int64)
    count = 0
    for k in range(0, short_t.size, BLOCK):
        s, idx = _nearest_block(long_t, short_t[k:k + BLOCK], max_diff)
        np.add(s, k, out=short_out[count:count + s.size])
        long_out[count:count + s.size] = idx
        count += s.size
    return short_out[:count], long_out[:count]


def _nearest_block(long_t: NDArray[np.float64], short_t: NDArray[np.float64],
                   max_diff: float) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    n = long_t.size
    inside = (short_t >= long_t[0] - max_diff) & (short_t <= long_t[-1] + max_diff)
    k = np.minimum(np.searchsorted(long_t, short_t, side="right"), n - 1)
    ub = long_t[k] - short_t
    lb = np.where(k > 0, short_t - long_t[np.maximum(k - 1, 0)], np.inf)
    take_k = (ub <= max_diff) & (ub < lb)
    take_prev = ~take_k & (lb <= max_diff) & (lb <= ub)
    accept = inside & (take_k | take_prev)
    idx = np.where(take_k, k, k - 1)
    short_idx = np.flatnonzero(accept)
    return short_idx, idx[accept]


def _nearest_unsorted(long_t: NDArray[np.float64], short_t: NDArray[np.float64],
                      max_diff: float) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """evo's fallback for unsorted stamps: per short stamp, the first long index of the
    smallest |long - s|, accepted if <= max_diff. Exact without the O(n m) search: |l - s|
    rounds monotonically on each side of s, so the minima form one run of sorted values
    next to s on each side; the smallest original index in those runs is argmin's answer."""
    order = np.argsort(long_t, kind="stable")
    v = long_t[order]
    n = v.size
    k = np.searchsorted(v, short_t, side="left")
    lo, hi = np.maximum(k - 1, 0), np.minimum(k, n - 1)
    d_lo = np.where(k > 0, np.abs(v[lo] - short_t), np.inf)
    d_hi = np.where(k < n, np.abs(v[hi] - short_t), np.inf)
    best = np.minimum(d_lo, d_hi)
    accept = best <= max_diff
    pick = np.full(short_t.size, np.iinfo(np.int64).max, dtype=np.int64)
    for start, step, dist in ((lo, -1, d_lo), (hi, 1, d_hi)):
        # walk each run of equal differences outwards; runs are as long as the repeats
        pos, live = start.copy(), accept & (dist == best)
        while live.any():
            pick[live] = np.minimum(pick[live], order[pos[live]])
            pos = pos + step
            inside = (pos >= 0) & (pos < n)
            live &= inside
            live[live] = np.abs(v[pos[live]] - short_t[live]) == best[live]
    short_idx = np.flatnonzero(accept)
    return short_idx, pick[accept]


def associate(ref: Trajectory, est: Trajectory, *, max_diff: float = 0.01, offset: float = 0.0) -> Matches:
    """Match poses by time stamp (evo `associate_trajectories` semantics)."""
    if max_diff < 0:
        raise EvaluationError(f"max_diff must be >= 0, got {max_diff}")
    # As evo, the offset moves the longer trajectory's stamps (subtracted from the reference,
    # added to the estimate), so borderline matches round exactly as there.
    est_is_short = len(est) <= len(ref)
    if est_is_short:  # x - 0.0 is x to the bit: no copy of a million stamps without an offset
        short_t, long_t = est.stamps, (ref.stamps - offset if offset else ref.stamps)
    else:
        short_t, long_t = ref.stamps, (est.stamps + offset if offset else est.stamps)
    if np.all(long_t[1:] >= long_t[:-1]):
        short_idx, long_idx = _nearest_within(long_t, short_t, max_diff)
    else:
        short_idx, long_idx = _nearest_unsorted(long_t, short_t, max_diff)
    if short_idx.size == 0:
        def span(t: Trajectory) -> str:
            return f"{t.stamps.min():.3f}..{t.stamps.max():.3f} s"

        raise EvaluationError(
            f"found no matching time stamps between reference ({span(ref)}) and estimate ({span(est)}) "
            f"with max_diff {max_diff} s and offset {offset} s"
        )
    if est_is_short:
        return Matches(ref_idx=long_idx, est_idx=short_idx)
    return Matches(ref_idx=short_idx, est_idx=long_idx)


def take(traj: Trajectory, idx: NDArray[np.int64]) -> Trajectory:
    """The poses at idx; the trajectory itself when every pose is taken in order (no copy)."""
    idx = np.asarray(idx)
    # n strictly increasing indices from 0 to n - 1 are 0..n - 1 (no np.diff: 8 bytes an index)
    if idx.size == len(traj) and (idx.size == 0 or (idx[0] == 0 and idx[-1] == idx.size - 1
                                                    and bool(np.all(idx[1:] > idx[:-1])))):
        return traj
    return replace(traj, stamps=traj.stamps[idx], positions=traj.positions[idx], quat_xyzw=traj.quat_xyzw[idx],
                   rotations=None if traj.rotations is None else traj.rotations[idx])


def associate_by_index(ref: Trajectory, est: Trajectory) -> Matches:
    """KITTI files have no stamps: pair by line index; lengths must agree."""
    if len(ref) != len(est):
        raise EvaluationError(f"index pairing needs equal lengths: reference {len(ref)}, estimate {len(est)} poses")
    idx = np.arange(len(ref))
    return Matches(idx, idx)


@dataclass(frozen=True)
class SyncOptions:
    """How estimate poses find their reference poses."""

    max_diff: float = 0.01  # s, nearest: largest stamp difference accepted
    offset: float = 0.0  # s, added to the estimate's stamps
    method: SyncMethod = SyncMethod.nearest
    max_gap: float = 0.2  # s, interpolate: longest reference gap bridged
    by_index: bool = False  # KITTI: pair line by line
    strict: bool = False  # refuse repeated or unsorted stamps


@dataclass(frozen=True)
class Matched:
    """The matched poses, in the estimate's order, and what matching saw on the way."""

    ref: Trajectory  # nearest: the reference's own stamps; interpolate: the estimate's, moved by the offset
    est: Trajectory
    ref_counts: StampCounts
    est_counts: StampCounts
    unmatched_est: int  # estimate poses left without a reference pose
    offset_s: float

    def summary(self) -> dict[str, object]:
        return {"offset_s": self.offset_s, "unmatched_est": self.unmatched_est,
                "repeated_stamps": {"reference": self.ref_counts.repeated, "estimate": self.est_counts.repeated},
                "unsorted_stamps": {"reference": self.ref_counts.unsorted, "estimate": self.est_counts.unsorted}}


def match(ref: Trajectory, est: Trajectory, opts: SyncOptions = SyncOptions()) -> Matched:
    """Check both trajectories, then pair them by index, by nearest stamp (evo) or by
    interpolating the reference at the estimate's stamps."""
    ref_counts = check_trajectory(ref, "reference", strict=opts.strict)
    est_counts = check_trajectory(est, "estimate", strict=opts.strict)
    if opts.method is SyncMethod.interpolate and not opts.by_index:
        ref_m, est_idx = interpolate_at(sorted_unique(ref), est.stamps + opts.offset, opts.max_gap)
        if est_idx.size == 0:
            raise EvaluationError(f"no estimate stamp (+ offset {opts.offset} s) falls inside the reference "
                                  f"with gaps up to max_gap {opts.max_gap} s")
    else:
        m = associate_by_index(ref, est) if opts.by_index else associate(ref, est, max_diff=opts.max_diff,
                                                                         offset=opts.offset)
        ref_m, est_idx = take(ref, m.ref_idx), m.est_idx
    unmatched = len(est) - distinct_count(est_idx)
    return Matched(ref_m, take(est, est_idx), ref_counts, est_counts, unmatched, float(opts.offset))
