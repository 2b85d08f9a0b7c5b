"""RPE block by block (rotations built only for the rows a block of pairs touches, issue 30) gives
the bits of the whole-array computation it replaced, for every relation, alignment, plane and
pair choice; the old computation is kept here as the oracle."""

from __future__ import annotations

import numpy as np
import pytest

from mrnc_eval.data import Trajectory
from mrnc_eval.evaluation import rpe as rpe_module
from mrnc_eval.evaluation.ape import AlignedPair, aligned_pair
from mrnc_eval.evaluation.modes import Relation
from mrnc_eval.evaluation.pairs import pairs_by_distance, pairs_by_frames
from mrnc_eval.evaluation.relations import error_values
from mrnc_eval.evaluation.sync import match
from mrnc_eval.geometry import lie

N = 2 * rpe_module.PAIR_BLOCK + 777


def _whole_arrays(pair: AlignedPair, i: np.ndarray, j: np.ndarray, relation: Relation) -> np.ndarray:
    """rpe's error computation before issue 30: every rotation at once."""
    q, p = pair.ref_xyz, pair.est_xyz
    if relation is Relation.point:
        return np.abs(np.linalg.norm(q[j] - q[i], axis=1) - np.linalg.norm(p[j] - p[i], axis=1))
    if relation is Relation.trans and pair.orthonormal:
        rel_p = np.einsum("nji,nj->ni", pair.est_rot[i], p[j] - p[i])
        rel_q = np.einsum("nji,nj->ni", pair.ref_rot[i], q[j] - q[i])
        return np.linalg.norm(rel_p - rel_q, axis=1)
    rq, tq = lie.relative(pair.ref_rot[i], q[i], pair.ref_rot[j], q[j])
    rp, tp = lie.relative(pair.est_rot[i], p[i], pair.est_rot[j], p[j])
    rot, trans = lie.relative(rq, tq, rp, tp)
    return error_values(rot, trans, relation)


def _trajectories(matrices: bool) -> tuple[Trajectory, Trajectory]:
    rng = np.random.default_rng(3)
    t = np.arange(N) * 0.01
    pos = np.cumsum(rng.normal(scale=0.05, size=(N, 3)), axis=0)
    q = rng.normal(size=(N, 4)) * rng.uniform(0.5, 2.0, size=(N, 1))  # not unit: evo normalises
    table = np.empty((8, N))  # the TUM reader's column-major layout: positions and quaternions are views
    table[0], table[1:4], table[4:8] = t, pos.T, q.T
    ref = Trajectory(table[0], table[1:4].T, table[4:8].T, name="ref")
    est_q = lie.quat_multiply(np.array([0.0, 0.0, np.sin(0.1), np.cos(0.1)]), q + rng.normal(scale=0.01, size=q.shape))
    est = Trajectory(t + 0.001, pos + rng.normal(scale=0.02, size=pos.shape) + 1.0, est_q, name="est")
    if matrices:  # KITTI: matrices as read, nearly orthonormal
        ref = Trajectory(ref.stamps, ref.positions, ref.quat_xyzw, name="ref",
                         rotations=lie.quat_xyzw_to_matrix(ref.quat_xyzw) * (1 + 1e-7))
    return ref, est


@pytest.mark.parametrize("matrices", [False, True])
@pytest.mark.parametrize(("align", "plane"), [("none", None), ("se3", None), ("sim3", "xy")])
def test_blockwise_rpe_equals_whole_arrays(matrices: bool, align: str, plane: str | None) -> None:
    ref, est = _trajectories(matrices)
    m = match(ref, est)
    pair = aligned_pair(m.ref, m.est, align, None, plane)
    pair_sets = [pairs_by_frames(N, 1, False), pairs_by_frames(N, 500, True),
                 pairs_by_distance(pair.est_xyz, 2.0, False, 0.1)]
    for i, j in pair_sets:
        assert i.size > rpe_module.PAIR_BLOCK or j.max() - j.min() > rpe_module.PAIR_BLOCK
        for relation in Relation:
            fresh = aligned_pair(m.ref, m.est, align, None, plane)
            got = rpe_module.pair_errors(fresh, i, j, relation)
            assert "est_rot" not in fresh.__dict__  # no (N, 3, 3) stack was built
            assert got.tobytes() == _whole_arrays(pair, i, j, relation).tobytes(), relation
