"""KITTI-style drift: relative translation (%) and rotation (deg/m) errors over segments.

Segments of 100..800 m are chosen on the reference path length, starting every 10 frames.
For logs shorter than 800 m the lengths are scaled to the log (state which were used).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrnc_eval.errors import EvaluationError
from mrnc_eval.evaluation import lie

KITTI_LENGTHS = (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0)


@dataclass(frozen=True)
class DriftResult:
    lengths_m: tuple[float, ...]
    trans_pct: dict[float, float]  # per segment length, mean over segments
    rot_deg_per_m: dict[float, float]
    mean_trans_pct: float
    mean_rot_deg_per_m: float
    n_segments: int


def segment_lengths(path_length: float) -> tuple[float, ...]:
    if path_length >= KITTI_LENGTHS[-1] * 1.05:
        return KITTI_LENGTHS
    # short log: eight lengths spread over up to 80 % of the path, the KITTI proportions
    scale = 0.8 * path_length / KITTI_LENGTHS[-1]
    return tuple(round(L * scale, 3) for L in KITTI_LENGTHS)


def kitti_drift(ref_poses: np.ndarray, est_poses: np.ndarray, *, step: int = 10,
                lengths: tuple[float, ...] | None = None) -> DriftResult:
    d = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ref_poses[:, :3, 3], axis=0), axis=1))])
    if d[-1] <= 0:
        raise EvaluationError("reference path has zero length; drift is undefined")
    lengths = lengths or segment_lengths(d[-1])
    starts = np.arange(0, d.size, step)
    trans, rot = {}, {}
    total = 0
    for L in lengths:
        ends = np.searchsorted(d, d[starts] + L, side="left")
        ok = ends < d.size
        i, j = starts[ok], ends[ok]
        if i.size == 0:
            continue
        dq = lie.compose(lie.inverse(ref_poses[i]), ref_poses[j])
        dp = lie.compose(lie.inverse(est_poses[i]), est_poses[j])
        e = lie.compose(lie.inverse(dp), dq)
        trans[L] = float(np.mean(np.linalg.norm(e[:, :3, 3], axis=1) / L) * 100.0)
        rot[L] = float(np.mean(np.degrees(lie.rotation_angle(e[:, :3, :3])) / L))
        total += i.size
    if not trans:
        raise EvaluationError(f"no segment of {lengths[0]} m fits in a {d[-1]:.1f} m path")
    return DriftResult(tuple(lengths), trans, rot, float(np.mean(list(trans.values()))),
                       float(np.mean(list(rot.values()))), total)
