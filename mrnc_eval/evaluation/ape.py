"""Absolute pose error: associate, align, E_i = P_i^-1 Q_i (estimate P, reference Q).

Translation relations need positions only, so rotations are built only for the rotation
relations (and lazily for callers that want aligned poses): 1e6 poses in ~0.3 s.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.data import Trajectory
from mrnc_eval.evaluation.align import (
    Alignment,
    align_positions,
    align_rotations,
    check_plane,
    estimate_alignment,
    project_positions,
    project_rotations,
)
from mrnc_eval.evaluation.decompose import Decomposition, decompose
from mrnc_eval.evaluation.modes import AlignMode, Relation, SyncMethod
from mrnc_eval.evaluation.relations import UNITS, check_relation, error_values
from mrnc_eval.evaluation.stats import error_stats
from mrnc_eval.evaluation.sync import Matched, SyncOptions, match
from mrnc_eval.geometry import lie
from mrnc_eval.geometry.point_fit import _kernels as _kernels

if TYPE_CHECKING:
    import pandas as pd


@dataclass(frozen=True, eq=False, kw_only=True)
class AlignedPair:
    """Matched reference Q and estimate P after alignment (and plane projection). The aligned
    positions are built when first asked for: APE on translation reads them block by block
    (`aligned_distances`) and never holds the (N, 3) aligned estimate."""

    ref: Trajectory  # matched, as read
    est: Trajectory  # matched, as read (not aligned)
    alignment: Alignment
    plane: str | None

    @cached_property
    def ref_xyz(self) -> NDArray[np.float64]:
        """(N, 3) matched reference positions (projected to the plane)."""
        q = self.ref.positions
        return project_positions(q, self.plane) if self.plane else q

    @cached_property
    def est_xyz(self) -> NDArray[np.float64]:
        """(N, 3) aligned estimate positions (projected to the plane)."""
        p = align_positions(self.est.positions, self.alignment)
        return project_positions(p, self.plane) if self.plane else p

    @property
    def orthonormal(self) -> bool:
        """Rotations come from quaternions (orthonormal to rounding), not matrices as read."""
        return self.ref.rotations is None and self.est.rotations is None

    @cached_property
    def ref_rot(self) -> NDArray[np.float64]:
        r = lie.rotations(self.ref)
        return project_rotations(r, self.plane) if self.plane else r

    @cached_property
    def est_rot(self) -> NDArray[np.float64]:
        r = align_rotations(lie.rotations(self.est), self.alignment)
        return project_rotations(r, self.plane) if self.plane else r


@dataclass(frozen=True, eq=False)
class ApeResult:
    """Absolute pose errors of one estimate, with their statistics."""

    name: str
    relation: Relation
    unit: str
    stats: dict[str, float]
    n: int  # matched poses
    span_s: float  # time covered by the matched poses
    ref_span_s: float  # time covered by the whole reference
    errors: NDArray[np.float64]
    stamps: NDArray[np.float64]  # the estimate's stamps of the matched poses
    alignment: Alignment
    pair: AlignedPair = field(repr=False)
    matching: Matched = field(repr=False)

    @property
    def transform(self) -> NDArray[np.float64]:
        """4x4 applied to the estimate, c R in the rotation block (evo's alignment_transformation_sim3)."""
        return self.alignment.sim3()

    @property
    def scale(self) -> float:
        return self.alignment.scale

    @property
    def est_xyz(self) -> NDArray[np.float64]:
        return self.pair.est_xyz

    @property
    def ref_xyz(self) -> NDArray[np.float64]:
        return self.pair.ref_xyz

    # Poses and trajectories (with quaternions) only when asked for: building 1e6 rotation
    # matrices and converting them back costs more than the whole evaluation.
    @cached_property
    def est_poses(self) -> NDArray[np.float64]:
        """(N, 4, 4) aligned (and projected) estimate."""
        return lie.homogeneous(self.pair.est_rot, self.pair.est_xyz)

    @cached_property
    def ref_poses(self) -> NDArray[np.float64]:
        """(N, 4, 4) matched (and projected) reference."""
        return lie.homogeneous(self.pair.ref_rot, self.pair.ref_xyz)

    @cached_property
    def est_aligned(self) -> Trajectory:
        return lie.from_poses(self.est_poses, self.pair.est)

    @cached_property
    def ref_matched(self) -> Trajectory:
        return lie.from_poses(self.ref_poses, self.pair.ref)

    def summary(self) -> dict[str, object]:
        return {"name": self.name, **self.stats, "n": self.n, "span_s": self.span_s, **self.matching.summary()}

    def alignment_summary(self) -> dict[str, object]:
        return self.alignment.summary()

    def decompose(self) -> Decomposition:
        """Signed along-track, cross-track, vertical and yaw errors of the aligned estimate."""
        return decompose(self.pair.ref_xyz, self.pair.est_xyz, self.pair.ref_rot, self.pair.est_rot)

    def to_dataframe(self, *, time_index: bool = False) -> pd.DataFrame:
        """One row per matched pose: t_s (the estimate's stamp), seconds_from_start,
        distance_from_start_m (along the reference, as evo's distances_from_start), the error
        (column "error_<unit>"), the aligned estimate and the reference positions (m); the
        statistics and the alignment in `.attrs`. `time_index`: indexed by t_s (a float index,
        for `.loc[t0:t1]` and resampling), else by row number."""
        import pandas as pd

        columns = {"t_s": self.stamps, "seconds_from_start": self.stamps - self.stamps[0],
                   "distance_from_start_m": path_lengths(self.ref_xyz),
                   f"error_{self.unit or 'unitless'}": self.errors}
        for k, axis in enumerate("xyz"):
            columns[f"est_{axis}"] = self.est_xyz[:, k]
            columns[f"ref_{axis}"] = self.ref_xyz[:, k]
        frame = pd.DataFrame(columns)
        if time_index:
            frame = frame.set_index("t_s", drop=False).rename_axis("time_s")
        frame.attrs.update(self.summary())
        frame.attrs["alignment"] = self.alignment_summary()
        return frame


def path_lengths(xyz: NDArray[np.float64]) -> NDArray[np.float64]:
    """Cumulative path length at each pose, m, from 0 (evo's `distances`)."""
    if xyz.shape[0] == 0:
        return np.zeros(0)
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xyz, axis=0), axis=1))])


ANGLE_BLOCK = 1 << 16  # poses per block of the quaternion angle route


def _distances(p: NDArray[np.float64], q: NDArray[np.float64]) -> NDArray[np.float64]:
    """|p_i - q_i| row by row, in blocks (elementwise: the same bits, a fraction of the memory)."""
    out = np.empty(p.shape[0])
    for k in range(0, out.size, ANGLE_BLOCK):
        out[k:k + ANGLE_BLOCK] = np.linalg.norm(p[k:k + ANGLE_BLOCK] - q[k:k + ANGLE_BLOCK], axis=1)
    return out


def aligned_distances(pair: AlignedPair) -> NDArray[np.float64]:
    """|align(p_i) - q_i| without the (N, 3) aligned estimate: each block aligned (align_positions
    is elementwise, so the same bits) and measured, then dropped (24 MB less for 1e6 poses)."""
    if "est_xyz" in pair.__dict__ or pair.plane:
        return _distances(pair.est_xyz, pair.ref_xyz)
    p, q = pair.est.positions, pair.ref.positions
    out = np.empty(p.shape[0])
    a = pair.alignment
    if _kernels is not None and a.mode is not AlignMode.none:  # one pass in C, the same arithmetic
        _kernels.aligned_distances(p, q, out, tuple(a.rotation.ravel()), tuple(a.translation), float(a.scale))
        return out
    for k in range(0, out.size, ANGLE_BLOCK):
        out[k:k + ANGLE_BLOCK] = _distances(align_positions(p[k:k + ANGLE_BLOCK], pair.alignment),
                                            q[k:k + ANGLE_BLOCK])
    return out


def _angles_from_quaternions(pair: AlignedPair) -> NDArray[np.float64]:
    """angle(P_i^-1 Q_i) from the quaternions (the aligned estimate's is q_R q_P): no 3x3
    matrices for 1e6 poses. Only for rotations that come from quaternions (not KITTI's
    matrices as read) and without plane projection."""
    q_align = None
    if pair.alignment.mode not in (AlignMode.none, AlignMode.scale):
        q_align = lie.matrix_to_quat_xyzw(pair.alignment.rotation[None])[0]
    out = np.empty(len(pair.est))
    for k in range(0, out.size, ANGLE_BLOCK):  # elementwise: blocks keep the temporaries small
        q_est = pair.est.quat_xyzw[k:k + ANGLE_BLOCK]
        if q_align is not None:
            q_est = lie.quat_multiply(q_align, q_est)
        out[k:k + ANGLE_BLOCK] = lie.quat_relative_angle(q_est, pair.ref.quat_xyzw[k:k + ANGLE_BLOCK])
    return out


def matched_pair(ref: Trajectory, est: Trajectory, *, max_diff: float, offset: float,
                 by_index: bool = False) -> tuple[Trajectory, Trajectory]:
    """The matched reference and estimate (evo's nearest-stamp association)."""
    m = match(ref, est, SyncOptions(max_diff=max_diff, offset=offset, by_index=by_index))
    return m.ref, m.est


def aligned_pair(ref_m: Trajectory, est_m: Trajectory, align: AlignMode | str, n_to_align: int | None,
                 plane: str | None) -> AlignedPair:
    """Order as evo: align (or scale, or origin), then project to the plane."""
    check_plane(plane)
    return AlignedPair(ref=ref_m, est=est_m, alignment=estimate_alignment(ref_m, est_m, align, n_to_align),
                       plane=plane)


def ape(ref: Trajectory, est: Trajectory, *, align: AlignMode | str = AlignMode.se3, n_to_align: int | None = None,
        relation: Relation | str = Relation.trans, max_diff: float = 0.01, offset: float = 0.0,
        plane: str | None = None, by_index: bool = False, strict: bool = False,
        sync: SyncMethod | str = SyncMethod.nearest, max_gap: float = 0.2) -> ApeResult:
    """APE of `est` against `ref`; `sync`, `max_gap`, `strict`: see evaluation.sync.SyncOptions."""
    relation = check_relation(relation)
    m = match(ref, est, SyncOptions(max_diff=max_diff, offset=offset, by_index=by_index, strict=strict,
                                    method=SyncMethod(sync), max_gap=max_gap))
    ref_m, est_m = m.ref, m.est
    pair = aligned_pair(ref_m, est_m, align, n_to_align, plane)
    if relation in (Relation.trans, Relation.point):
        errors = aligned_distances(pair)
    elif relation in (Relation.angle_deg, Relation.angle_rad) and pair.orthonormal and not plane:
        errors = _angles_from_quaternions(pair)
        if relation is Relation.angle_deg:  # in place: elementwise, the same bits, 8 MB less for 1e6 poses
            np.degrees(errors, out=errors)
    else:  # E = P^-1 Q
        rot, trans = lie.relative(pair.est_rot, pair.est_xyz, pair.ref_rot, pair.ref_xyz)
        errors = error_values(rot, trans, relation)
    return ApeResult(
        name=est.name, relation=relation, unit=UNITS[relation], stats=error_stats(errors), n=int(errors.size),
        span_s=float(np.ptp(est_m.stamps)), ref_span_s=float(np.ptp(ref.stamps)),
        errors=errors, stamps=est_m.stamps, alignment=pair.alignment, pair=pair, matching=m,
    )
