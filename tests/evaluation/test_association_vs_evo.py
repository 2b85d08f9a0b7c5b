"""Association and RPE pair selection equal evo's on adversarial inputs: exact ties, bounds
hit exactly, offsets, all length orders, standing still (runs of equal path length)."""

from __future__ import annotations

import numpy as np
import pytest

from mrnc_eval.data import Trajectory
from mrnc_eval.evaluation.pairs import pairs_by_distance
from mrnc_eval.evaluation.rpe import rpe
from mrnc_eval.evaluation.sync import associate, take
from tests.evaluation.evo_reference import evo_rpe, make_pair, require_evo, to_evo

require_evo()


def _traj(stamps: np.ndarray, name: str) -> Trajectory:
    n = stamps.size
    return Trajectory(stamps, np.c_[np.arange(n, dtype=float), np.zeros(n), np.zeros(n)],
                      np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)), name=name)


def _stamp_sets(rng: np.random.Generator):
    """(ref stamps, est stamps, max_diff, offset) cases built to hit evo's corner rules."""
    grid = np.arange(200) / 64.0  # dyadic: differences are exact, so ties are real ties
    yield grid, grid[:150] + 1 / 128.0, 1 / 128.0, 0.0  # every est stamp halfway: tie -> earlier
    yield grid, grid + 1 / 128.0, 1 / 128.0, 0.0  # equal length: the estimate is the short one
    yield grid[:120], grid + 1 / 256.0, 1 / 256.0, 0.0  # est longer, |diff| == max_diff exactly
    yield grid, grid[::3] + 0.5, 1 / 64.0, 0.5 - 1 / 128.0  # offset leaves exact ties
    yield grid[:90], grid, 1 / 64.0, -1 / 128.0  # est longer with an offset: est + offset
    yield grid, grid[10:50], 0.0, 0.0  # max_diff 0: exact matches only
    # decimal (millisecond) stamps where "ref - offset" and "est + offset" round differently
    # at |diff| == max_diff: evo moves the longer trajectory's stamps, so must we
    base = 31.56899116720069
    yield np.round(base + np.arange(300) * 0.01, 3), np.round(base + np.arange(200) * 0.01 + 0.005, 3), 0.002, -0.003
    for _ in range(20):  # jittered stamps, random lengths, rates and offsets
        n_ref, n_est = rng.integers(20, 400, size=2)
        ref = np.sort(rng.uniform(0, 10, n_ref))
        est = np.sort(rng.uniform(-1, 11, n_est))
        yield ref, est, float(rng.choice([0.005, 0.01, 0.05])), float(rng.uniform(-0.02, 0.02))


def test_association_equals_evo_on_corner_cases() -> None:
    from evo.core import sync

    rng = np.random.default_rng(7)
    for case, (ref_t, est_t, max_diff, offset) in enumerate(_stamp_sets(rng)):
        ref, est = _traj(np.unique(ref_t), "ref"), _traj(np.unique(est_t), "est")
        try:
            r_evo, e_evo = sync.associate_trajectories(to_evo(ref), to_evo(est), max_diff=max_diff, offset_2=offset)
        except sync.SyncException:
            with pytest.raises(Exception, match="no matching time stamps"):
                associate(ref, est, max_diff=max_diff, offset=offset)
            continue
        m = associate(ref, est, max_diff=max_diff, offset=offset)
        np.testing.assert_array_equal(take(ref, m.ref_idx).stamps, r_evo.timestamps, err_msg=f"case {case}")
        np.testing.assert_array_equal(take(est, m.est_idx).stamps, e_evo.timestamps, err_msg=f"case {case}")


def _with_standstills(traj: Trajectory, rng: np.random.Generator) -> Trajectory:
    """Hold the position over a few random stretches, as a robot waiting at a gate does."""
    pos = traj.positions.copy()
    for start in rng.choice(len(traj) - 40, size=6, replace=False):
        pos[start:start + rng.integers(5, 40)] = pos[start]
    return Trajectory(traj.stamps, pos, traj.quat_xyzw, name=traj.name)


@pytest.mark.parametrize("delta", [0.5, 1.0, 3.0])
def test_all_pairs_by_distance_with_standstills_equal_evo(delta: float) -> None:
    from evo.core import filters

    rng = np.random.default_rng(int(delta * 10))
    ref, est = make_pair(n=800, seed=4)
    est = _with_standstills(est, rng)
    pos = est.positions
    poses = [np.block([[np.eye(3), p[:, None]], [np.zeros((1, 3)), np.ones((1, 1))]]) for p in pos]
    theirs = np.array(filters.filter_pairs_by_path(poses, delta, delta * 0.1, all_pairs=True))
    i, j = pairs_by_distance(pos, delta, all_pairs=True, tol=0.1)
    np.testing.assert_array_equal(np.c_[i, j], theirs)
    ours = rpe(ref, est, delta=delta, delta_unit="m", all_pairs=True, relation="trans", align="none")
    stats, err = evo_rpe(ref, est, relation="trans", delta=delta, unit="m", all_pairs=True, align="none")
    np.testing.assert_allclose(ours.errors, err, rtol=1e-9, atol=1e-12)
    assert ours.stats["sse"] == pytest.approx(stats["sse"], rel=1e-12)


def test_consecutive_pairs_by_distance_with_standstills_equal_evo() -> None:
    from evo.core import filters

    rng = np.random.default_rng(1)
    _, est = make_pair(n=800, seed=9)
    pos = _with_standstills(est, rng).positions
    poses = [np.block([[np.eye(3), p[:, None]], [np.zeros((1, 3)), np.ones((1, 1))]]) for p in pos]
    for delta in (0.1, 0.7, 2.0):
        theirs = np.array(filters.filter_pairs_by_path(poses, delta, 0.0, all_pairs=False))
        i, j = pairs_by_distance(pos, delta, all_pairs=False)
        np.testing.assert_array_equal(np.c_[i, j], theirs, err_msg=str(delta))


def test_degenerate_umeyama_is_a_clear_error_like_evo() -> None:
    """A straight-line path: evo raises GeometryException; we raise EvaluationError saying why.
    Yaw alignment of a path standing still is refused too."""
    from evo.core import geometry

    from mrnc_eval.errors import EvaluationError
    from mrnc_eval.evaluation.ape import ape

    n = 50
    line = Trajectory(np.arange(n) * 0.1, np.c_[np.arange(n, dtype=float), np.zeros(n), np.zeros(n)],
                      np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)), name="line")
    with pytest.raises(geometry.GeometryException):
        geometry.umeyama_alignment(line.positions.T, line.positions.T + 1.0, False)
    with pytest.raises(EvaluationError, match="collinear"):
        ape(line, line, align="se3")
    still = Trajectory(line.stamps, np.zeros((n, 3)), line.quat_xyzw, name="still")
    with pytest.raises(EvaluationError, match="degenerate yaw"):
        ape(still, still, align="yaw")
    assert ape(line, line, align="origin").stats["max"] == 0.0  # origin alignment needs no spread
