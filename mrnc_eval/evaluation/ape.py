"""Absolute pose error: associate, align, E_i = P_i^-1 Q_i (estimate P, reference Q)."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.data import Trajectory
from mrnc_eval.evaluation import lie
from mrnc_eval.evaluation.align import Alignment, apply_alignment, estimate_alignment, project_to_plane
from mrnc_eval.evaluation.relations import UNITS, check_relation, error_values
from mrnc_eval.evaluation.stats import error_stats
from mrnc_eval.evaluation.sync import associate, associate_by_index, check_trajectory, take


@dataclass(frozen=True, eq=False)
class ApeResult:
    name: str
    relation: str
    unit: str
    stats: dict[str, float]
    n: int  # matched poses
    span_s: float  # time covered by the matched poses
    ref_span_s: float  # time covered by the whole reference
    errors: NDArray[np.float64]
    stamps: NDArray[np.float64]  # the estimate's stamps of the matched poses
    alignment: Alignment
    est_poses: NDArray[np.float64] = field(repr=False)  # (N, 4, 4) aligned estimate
    ref_poses: NDArray[np.float64] = field(repr=False)  # (N, 4, 4) matched reference
    _est: Trajectory = field(repr=False)
    _ref: Trajectory = field(repr=False)

    # Trajectories (with quaternions) only when asked for: converting 1e6 rotation matrices
    # back to quaternions costs more than the whole evaluation.
    @cached_property
    def est_aligned(self) -> Trajectory:
        return lie.from_poses(self.est_poses, self._est)

    @cached_property
    def ref_matched(self) -> Trajectory:
        return lie.from_poses(self.ref_poses, self._ref)

    def summary(self) -> dict[str, float | int | str]:
        return {"name": self.name, **self.stats, "n": self.n, "span_s": self.span_s}


def matched_pair(ref: Trajectory, est: Trajectory, *, max_diff: float, offset: float,
                 by_index: bool = False) -> tuple[Trajectory, Trajectory]:
    ref = check_trajectory(ref, "reference")
    est = check_trajectory(est, "estimate")
    m = associate_by_index(ref, est) if by_index else associate(ref, est, max_diff=max_diff, offset=offset)
    return take(ref, m.ref_idx), take(est, m.est_idx)


def aligned_poses(ref_m: Trajectory, est_m: Trajectory, align: str, n_to_align: int | None,
                  plane: str | None) -> tuple[NDArray, NDArray, Alignment]:
    q = lie.poses(ref_m)
    p = lie.poses(est_m)
    a = estimate_alignment(q, p, align, n_to_align)
    p = apply_alignment(p, a)
    if plane:
        q, p = project_to_plane(q, plane), project_to_plane(p, plane)
    return q, p, a


def ape(ref: Trajectory, est: Trajectory, *, align: str = "se3", n_to_align: int | None = None,
        relation: str = "trans", max_diff: float = 0.01, offset: float = 0.0, plane: str | None = None,
        by_index: bool = False) -> ApeResult:
    check_relation(relation)
    ref_m, est_m = matched_pair(ref, est, max_diff=max_diff, offset=offset, by_index=by_index)
    q, p, a = aligned_poses(ref_m, est_m, align, n_to_align, plane)
    if relation in ("trans", "point"):
        errors = np.linalg.norm(p[:, :3, 3] - q[:, :3, 3], axis=1)
    else:
        errors = error_values(lie.compose(lie.inverse(p), q), relation)
    return ApeResult(
        name=est.name, relation=relation, unit=UNITS[relation], stats=error_stats(errors), n=int(errors.size),
        span_s=float(est_m.stamps[-1] - est_m.stamps[0]), ref_span_s=float(ref.stamps.max() - ref.stamps.min()),
        errors=errors, stamps=est_m.stamps, alignment=a, est_poses=p, ref_poses=q, _est=est_m, _ref=ref_m,
    )
