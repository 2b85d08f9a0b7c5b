"""KITTI-style drift: relative translation (%) and rotation (deg/m) errors over segments.

As the KITTI odometry devkit: segments start every `step` frames; a segment of length L
ends at the first pose whose reference path distance exceeds the start's by more than L;
E = (P_i^-1 P_j)^-1 (Q_i^-1 Q_j); t_err = |t(E)| / L, r_err = angle(E) / L, averaged over
the segments of each length, then over lengths. Lengths are 100..800 m; logs shorter than
~840 m use the same eight proportions scaled to 80 % of the path (the result states them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.data import F64, Trajectory
from mrnc_eval.errors import EvaluationError
from mrnc_eval.evaluation.modes import AlignMode
from mrnc_eval.geometry import lie

KITTI_LENGTHS = (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0)


@dataclass(frozen=True)
class DriftResult:
    lengths_m: tuple[float, ...]  # the segment lengths used
    trans_pct: dict[float, float]  # per segment length, mean over its segments
    rot_deg_per_m: dict[float, float]
    segments: dict[float, int]  # per segment length, how many segments fit
    mean_trans_pct: float  # mean over the lengths that had segments
    mean_rot_deg_per_m: float
    n_segments: int
    path_length_m: float  # reference path length

    def summary(self) -> dict[str, object]:
        return {"lengths_m": list(self.lengths_m), "path_length_m": self.path_length_m,
                "mean_trans_pct": self.mean_trans_pct, "mean_rot_deg_per_m": self.mean_rot_deg_per_m,
                "n_segments": self.n_segments,
                "per_length": [{"length_m": L, "trans_pct": self.trans_pct[L], "rot_deg_per_m": self.rot_deg_per_m[L],
                                "segments": self.segments[L]} for L in self.lengths_m if L in self.trans_pct]}


def segment_lengths(path_length: float) -> tuple[float, ...]:
    if path_length >= KITTI_LENGTHS[-1] * 1.05:
        return KITTI_LENGTHS
    scale = 0.8 * path_length / KITTI_LENGTHS[-1]
    return tuple(round(L * scale, 3) for L in KITTI_LENGTHS)


def kitti_drift_rt(ref_rot: F64, ref_xyz: F64, est_rot: F64, est_xyz: F64, *, step: int = 10,
                   lengths: tuple[float, ...] | None = None) -> DriftResult:
    """Drift from matched rotations (N, 3, 3) and positions (N, 3) of reference and estimate."""
    d = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ref_xyz, axis=0), axis=1))])
    if d[-1] <= 0:
        raise EvaluationError("reference path has zero length; drift is undefined")
    lengths = tuple(lengths or segment_lengths(float(d[-1])))
    starts = np.arange(0, d.size, step)
    trans, rot, count = {}, {}, {}
    for L in lengths:  # eight lengths; each one vectorised over all its segments
        ends = np.searchsorted(d, d[starts] + L, side="right")  # first pose beyond start + L
        ok = ends < d.size
        i, j = starts[ok], ends[ok]
        if i.size == 0:
            continue
        rq, tq = lie.relative(ref_rot[i], ref_xyz[i], ref_rot[j], ref_xyz[j])
        rp, tp = lie.relative(est_rot[i], est_xyz[i], est_rot[j], est_xyz[j])
        re, te = lie.relative(rp, tp, rq, tq)
        trans[L] = float(np.mean(np.linalg.norm(te, axis=1) / L) * 100.0)
        rot[L] = float(np.mean(np.degrees(lie.rotation_angle(re)) / L))
        count[L] = int(i.size)
    if not trans:
        raise EvaluationError(f"no segment of {lengths[0]} m fits in a {d[-1]:.1f} m path")
    return DriftResult(lengths, trans, rot, count, float(np.mean(list(trans.values()))),
                       float(np.mean(list(rot.values()))), sum(count.values()), float(d[-1]))


def kitti_drift(ref_poses: NDArray[np.float64], est_poses: NDArray[np.float64], *, step: int = 10,
                lengths: tuple[float, ...] | None = None) -> DriftResult:
    """Drift from matched (N, 4, 4) poses."""
    return kitti_drift_rt(ref_poses[:, :3, :3], ref_poses[:, :3, 3], est_poses[:, :3, :3], est_poses[:, :3, 3],
                          step=step, lengths=lengths)


def drift(ref: Trajectory, est: Trajectory, *, align: AlignMode | str = AlignMode.none, max_diff: float = 0.01,
          offset: float = 0.0, by_index: bool = False, step: int = 10,
          lengths: tuple[float, ...] | None = None) -> DriftResult:
    """Associate, align (drift is invariant to rigid alignment; sim3/scale change it), then drift."""
    from mrnc_eval.evaluation.ape import aligned_pair, matched_pair

    ref_m, est_m = matched_pair(ref, est, max_diff=max_diff, offset=offset, by_index=by_index)
    pair = aligned_pair(ref_m, est_m, align, None, None)
    return kitti_drift_rt(pair.ref_rot, pair.ref_xyz, pair.est_rot, pair.est_xyz, step=step, lengths=lengths)
