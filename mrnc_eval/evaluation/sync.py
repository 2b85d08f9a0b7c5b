"""Association of two trajectories by time stamp, with evo's semantics.

For each stamp of the shorter trajectory (the estimate on equal length), the closest
stamp of the longer one within `max_diff` is taken; bounds are inclusive and ties go to
the earlier stamp. Matches need not be one-to-one. `offset` is added to the estimate's
clock (applied, as in evo, to the longer trajectory's stamps). Unlike evo, duplicate
stamps, non-finite values and single-pose trajectories are errors, and unsorted input is
sorted first (evo falls back to a per-stamp argmin search and keeps the input order).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.data import Trajectory
from mrnc_eval.errors import EvaluationError


@dataclass(frozen=True)
class Matches:
    ref_idx: NDArray[np.int64]
    est_idx: NDArray[np.int64]


def check_trajectory(traj: Trajectory, role: str) -> Trajectory:
    """Reject what would make association meaningless; sort unsorted input."""
    label = f"{role} trajectory {traj.name!r}" if traj.name else f"{role} trajectory"
    if len(traj) < 2:
        raise EvaluationError(f"{label} has {len(traj)} pose(s); at least 2 are needed")
    if not (np.isfinite(traj.stamps).all() and np.isfinite(traj.positions).all() and np.isfinite(traj.quat_xyzw).all()):
        raise EvaluationError(f"{label} contains NaN or infinite values")
    order = np.argsort(traj.stamps, kind="stable")
    stamps = traj.stamps[order]
    dup = int(np.count_nonzero(np.diff(stamps) == 0))
    if dup:
        raise EvaluationError(f"{label} has {dup} duplicate time stamp(s); remove them before evaluating")
    if np.any(order != np.arange(order.size)):
        return Trajectory(stamps, traj.positions[order], traj.quat_xyzw[order], traj.name, traj.frame_id,
                          traj.child_frame_id)
    return traj


def _nearest_within(long_t: NDArray[np.float64], short_t: NDArray[np.float64],
                    max_diff: float) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(short indices, long indices) of accepted matches; long_t sorted."""
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


def associate(ref: Trajectory, est: Trajectory, *, max_diff: float = 0.01, offset: float = 0.0) -> Matches:
    """Match poses by time stamp (evo `associate_trajectories` semantics)."""
    if max_diff < 0:
        raise EvaluationError(f"max_diff must be >= 0, got {max_diff}")
    # As evo, the offset moves the longer trajectory's stamps (subtracted from the reference,
    # added to the estimate), so borderline matches round exactly as there.
    est_is_short = len(est) <= len(ref)
    if est_is_short:
        short_t, long_t = est.stamps, ref.stamps - offset
    else:
        short_t, long_t = ref.stamps, est.stamps + offset
    short_idx, long_idx = _nearest_within(long_t, short_t, max_diff)
    if short_idx.size == 0:
        def span(t: Trajectory) -> str:
            return f"{t.stamps[0]:.3f}..{t.stamps[-1]:.3f} s"

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
    if idx.size == len(traj) and (idx.size == 0 or (idx[0] == 0 and idx[-1] == idx.size - 1
                                                    and np.all(np.diff(idx) == 1))):
        return traj
    return Trajectory(traj.stamps[idx], traj.positions[idx], traj.quat_xyzw[idx], traj.name, traj.frame_id,
                      traj.child_frame_id)


def associate_by_index(ref: Trajectory, est: Trajectory) -> Matches:
    """KITTI files have no stamps: pair by line index; lengths must agree."""
    if len(ref) != len(est):
        raise EvaluationError(f"index pairing needs equal lengths: reference {len(ref)}, estimate {len(est)} poses")
    idx = np.arange(len(ref))
    return Matches(idx, idx)
