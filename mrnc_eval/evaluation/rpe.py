"""Relative pose error: E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) over index pairs."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.data import Trajectory
from mrnc_eval.errors import EvaluationError
from mrnc_eval.evaluation.align import Alignment, align_rotations, project_rotations
from mrnc_eval.evaluation.ape import AlignedPair, aligned_pair, path_lengths
from mrnc_eval.evaluation.modes import AlignMode, DeltaUnit, PairsFrom, Relation, SyncMethod, parse_choice
from mrnc_eval.evaluation.pairs import pairs_by_distance, pairs_by_frames
from mrnc_eval.evaluation.relations import UNITS, check_relation, error_values
from mrnc_eval.evaluation.stats import error_stats
from mrnc_eval.evaluation.sync import Matched, SyncOptions, match
from mrnc_eval.geometry import lie

if TYPE_CHECKING:
    import pandas as pd


@dataclass(frozen=True)
class RpeResult:
    name: str
    relation: Relation
    unit: str
    delta: float
    delta_unit: DeltaUnit
    pairs_from: PairsFrom
    stats: dict[str, float]
    n: int  # pairs
    span_s: float
    errors: NDArray[np.float64]
    stamps: NDArray[np.float64]  # estimate stamps at the pair ends j
    matching: Matched = field(repr=False)
    alignment: Alignment | None = field(default=None, repr=False)
    pair: AlignedPair | None = field(default=None, repr=False)
    pair_ends: NDArray[np.int64] | None = field(default=None, repr=False)  # j of each pair, into the matched poses

    def alignment_summary(self) -> dict[str, object]:
        return self.alignment.summary() if self.alignment is not None else {"mode": "none", "n_to_align": None,
                                                                            "scale": 1.0, "transform": None}

    def summary(self) -> dict[str, object]:
        return {"name": self.name, **self.stats, "n": self.n, "span_s": self.span_s, **self.matching.summary()}

    def to_dataframe(self, *, time_index: bool = False) -> pd.DataFrame:
        """One row per pair: t_s (the estimate's stamp at the pair's end), seconds_from_start (from
        the first matched pose), distance_from_start_m (along the reference to the pair's end), the
        error (column "error_<unit>"); the statistics and alignment in `.attrs`. `time_index`:
        indexed by t_s."""
        import pandas as pd

        columns = {"t_s": self.stamps, "seconds_from_start": self.stamps - self.matching.est.stamps[0],
                   f"error_{self.unit or 'unitless'}": self.errors}
        if self.pair is not None and self.pair_ends is not None:  # along the reference, to each pair's end
            columns["distance_from_start_m"] = path_lengths(self.pair.ref_xyz)[self.pair_ends]
        frame = pd.DataFrame(columns)
        if time_index:
            frame = frame.set_index("t_s", drop=False).rename_axis("time_s")
        frame.attrs.update(self.summary())
        frame.attrs["alignment"] = self.alignment_summary()
        return frame


PAIR_BLOCK = 1 << 15  # pairs per block: rotations are built for the rows a block touches only


class _RowRotations:
    """Rotations of a matched trajectory's rows lo..hi (aligned and projected as AlignedPair's
    ref_rot / est_rot), built from a row slice: the same layout as the whole array, so the same
    bits (numpy's einsum rounds by layout), without the (N, 3, 3) stack (72 MB for 1e6 poses)."""

    def __init__(self, pair: AlignedPair, which: str) -> None:
        self.traj = pair.est if which == "est" else pair.ref
        self.alignment = pair.alignment if which == "est" else None
        self.plane = pair.plane

    def at(self, idx: NDArray[np.int64]) -> NDArray[np.float64]:
        lo, hi = int(idx.min()), int(idx.max()) + 1
        if self.traj.rotations is not None:
            r = self.traj.rotations[lo:hi]
        else:
            r = lie.quat_xyzw_to_matrix(self.traj.quat_xyzw[lo:hi])
        if self.alignment is not None:
            r = align_rotations(r, self.alignment)
        if self.plane:
            r = project_rotations(r, self.plane)
        return r[idx - lo]


def pair_errors(pair: AlignedPair, i: NDArray[np.int64], j: NDArray[np.int64],
                relation: Relation) -> NDArray[np.float64]:
    """The error of each pose pair (i, j), block by block (each pair on its own: the same bits as
    the whole arrays at once, with temporaries of a block)."""
    q, p = pair.ref_xyz, pair.est_xyz
    if relation is Relation.point:  # | |q_j - q_i| - |p_j - p_i| |, no rotations
        point: NDArray[np.float64] = np.abs(np.linalg.norm(q[j] - q[i], axis=1) - np.linalg.norm(p[j] - p[i], axis=1))
        return point
    ref_rot, est_rot = _RowRotations(pair, "ref"), _RowRotations(pair, "est")
    out = np.empty(i.size)
    for k in range(0, i.size, PAIR_BLOCK):
        ib, jb = i[k:k + PAIR_BLOCK], j[k:k + PAIR_BLOCK]
        if relation is Relation.trans and pair.orthonormal:  # | R_Pi^T (p_j - p_i) - R_Qi^T (q_j - q_i) |
            rel_p = np.einsum("nji,nj->ni", est_rot.at(ib), p[jb] - p[ib])
            rel_q = np.einsum("nji,nj->ni", ref_rot.at(ib), q[jb] - q[ib])
            out[k:k + PAIR_BLOCK] = np.linalg.norm(rel_p - rel_q, axis=1)
        else:  # E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j); also trans for matrices as read (not quite orthonormal)
            rq, tq = lie.relative(ref_rot.at(ib), q[ib], ref_rot.at(jb), q[jb])
            rp, tp = lie.relative(est_rot.at(ib), p[ib], est_rot.at(jb), p[jb])
            rot, trans = lie.relative(rq, tq, rp, tp)
            out[k:k + PAIR_BLOCK] = error_values(rot, trans, relation)
    return out


def rpe(ref: Trajectory, est: Trajectory, *, delta: float = 1.0, delta_unit: DeltaUnit | str = DeltaUnit.frames,
        all_pairs: bool = False, align: AlignMode | str = AlignMode.none, n_to_align: int | None = None,
        relation: Relation | str = Relation.trans, max_diff: float = 0.01, offset: float = 0.0,
        plane: str | None = None, pairs_from: PairsFrom | str = PairsFrom.estimate, tol: float = 0.1,
        by_index: bool = False, strict: bool = False, sync: SyncMethod | str = SyncMethod.nearest,
        max_gap: float = 0.2) -> RpeResult:
    relation = check_relation(relation)
    pairs_from = parse_choice(PairsFrom, pairs_from, "pairs_from")
    delta_unit = parse_choice(DeltaUnit, delta_unit, "delta unit")
    m = match(ref, est, SyncOptions(max_diff=max_diff, offset=offset, by_index=by_index, strict=strict,
                                    method=SyncMethod(sync), max_gap=max_gap))
    ref_m, est_m = m.ref, m.est
    pair = aligned_pair(ref_m, est_m, align, n_to_align, plane)
    q, p = pair.ref_xyz, pair.est_xyz
    if delta_unit is DeltaUnit.frames:
        if float(delta) != int(delta):
            raise EvaluationError(f"delta in frames must be a whole number, got {delta}")
        i, j = pairs_by_frames(len(p), int(delta), all_pairs)
    else:
        i, j = pairs_by_distance(q if pairs_from is PairsFrom.reference else p, float(delta), all_pairs, tol)
    if i.size == 0:
        raise EvaluationError(f"no pose pairs for delta {delta} {delta_unit} (trajectory too short)")
    errors = pair_errors(pair, i, j, relation)
    return RpeResult(
        name=est.name, relation=relation, unit=UNITS[relation], delta=float(delta), delta_unit=delta_unit,
        pairs_from=pairs_from, stats=error_stats(errors), n=int(errors.size),
        span_s=float(np.ptp(est_m.stamps)), errors=errors, stamps=est_m.stamps[j], matching=m,
        alignment=pair.alignment, pair=pair, pair_ends=j,
    )
