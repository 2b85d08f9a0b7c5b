"""Resampling a trajectory at given stamps: positions linearly, rotations by slerp.

Used by `--sync interpolate`: the reference is evaluated at each estimate stamp (moved to
the reference clock by the offset), but only inside a bracket of two reference poses no
more than `max_gap` seconds apart; stamps outside the reference or across a longer gap
stay unmatched (and are counted), never extrapolated.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.data import Trajectory
from mrnc_eval.errors import EvaluationError


def sorted_unique(traj: Trajectory) -> Trajectory:
    """Stamps strictly increasing: sorted (stable), the first pose of each repeated stamp kept."""
    order = np.argsort(traj.stamps, kind="stable")
    keep = np.ones(order.size, dtype=bool)
    keep[1:] = np.diff(traj.stamps[order]) > 0
    idx = order[keep]
    if idx.size == len(traj) and np.all(idx == np.arange(idx.size)):
        return traj
    return replace(traj, stamps=traj.stamps[idx], positions=traj.positions[idx], quat_xyzw=traj.quat_xyzw[idx],
                   rotations=None if traj.rotations is None else traj.rotations[idx])


def slerp(q0: NDArray[np.float64], q1: NDArray[np.float64], f: NDArray[np.float64]) -> NDArray[np.float64]:
    """Spherical linear interpolation of (N, 4) quaternions at fractions f in [0, 1], along
    the shorter arc; the result is a unit quaternion."""
    q0 = q0 / np.linalg.norm(q0, axis=1, keepdims=True)
    q1 = q1 / np.linalg.norm(q1, axis=1, keepdims=True)
    dot = np.einsum("ij,ij->i", q0, q1)
    q1 = np.where(dot[:, None] < 0, -q1, q1)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    small = theta < 1e-9  # nearly equal: the linear blend is exact to rounding
    s = np.sin(np.where(small, 1.0, theta))
    w0 = np.where(small, 1.0 - f, np.sin((1.0 - f) * theta) / s)
    w1 = np.where(small, f, np.sin(f * theta) / s)
    q = w0[:, None] * q0 + w1[:, None] * q1
    out: NDArray[np.float64] = q / np.linalg.norm(q, axis=1, keepdims=True)
    return out


def interpolate_at(traj: Trajectory, stamps: NDArray[np.float64],
                   max_gap: float) -> tuple[Trajectory, NDArray[np.int64]]:
    """`traj` (strictly increasing stamps) at each of `stamps` that falls inside a bracket of
    at most `max_gap` s (a stamp equal to a pose's is always kept). Returns the resampled
    trajectory (stamps as asked) and the indices into `stamps` that were resampled."""
    if max_gap <= 0:
        raise EvaluationError(f"max_gap must be > 0 s, got {max_gap}")
    t = traj.stamps
    k = np.searchsorted(t, stamps, side="left")  # t[k - 1] < s <= t[k]
    exact = (k < t.size) & (t[np.minimum(k, t.size - 1)] == stamps)
    inside = (k > 0) & (k < t.size)
    i0, i1 = np.maximum(k - 1, 0), np.minimum(k, t.size - 1)
    ok = exact | (inside & (t[i1] - t[i0] <= max_gap))
    idx = np.flatnonzero(ok)
    i0, i1, s = i0[idx], i1[idx], stamps[idx]
    i0 = np.where(exact[idx], i1, i0)
    span = t[i1] - t[i0]
    f = np.where(span > 0, (s - t[i0]) / np.where(span > 0, span, 1.0), 0.0)
    pos = traj.positions[i0] + f[:, None] * (traj.positions[i1] - traj.positions[i0])
    quat = slerp(traj.quat_xyzw[i0], traj.quat_xyzw[i1], f)
    return replace(traj, stamps=s.copy(), positions=pos, quat_xyzw=quat, rotations=None), idx
