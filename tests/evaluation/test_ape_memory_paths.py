"""The low-memory routes of ape (issue 30) give the same bits as the whole-array ones they replace:
association block by block, distances from the aligned estimate block by block, stamp checks by
neighbour comparison. Sizes span several blocks, with gaps, repeats and unmatched poses."""

from __future__ import annotations

import numpy as np

from mrnc_eval.data import Trajectory
from mrnc_eval.evaluation import sync
from mrnc_eval.evaluation.ape import _distances, aligned_distances, aligned_pair, ape
from mrnc_eval.geometry.lie import quat_multiply

N = 3 * sync.BLOCK + 1234


def _pair(seed: int) -> tuple[Trajectory, Trajectory]:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.choice([0.01, 0.01, 0.02, 0.0, 0.5], size=N))  # gaps and repeated stamps
    pos = np.cumsum(rng.normal(size=(N, 3)), axis=0)
    q = rng.normal(size=(N, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    est_t = t[::2] + rng.uniform(-0.012, 0.012, size=t[::2].size)  # some beyond max_diff
    est_q = quat_multiply(np.array([0.0, 0.0, np.sin(0.2), np.cos(0.2)]), q[::2])
    est = Trajectory(np.sort(est_t), pos[::2] + rng.normal(scale=0.1, size=(est_t.size, 3)) + 3.0, est_q,
                     name="est")
    return Trajectory(t, pos, q, name="ref"), est


def test_blockwise_association_equals_one_block() -> None:
    ref, est = _pair(0)
    for short, long_ in ((est.stamps, ref.stamps), (ref.stamps[: N // 3], est.stamps)):
        got = sync._nearest_within(long_, short, 0.01)
        whole = sync._nearest_block(long_, short, 0.01)
        assert 0 < got[0].size < short.size  # some poses unmatched: the trimming is exercised
        np.testing.assert_array_equal(got[0], whole[0])
        np.testing.assert_array_equal(got[1], whole[1])


def test_neighbour_comparisons_count_like_diff() -> None:
    ref, _ = _pair(1)
    t = ref.stamps.copy()
    t[[5, 900, 70_000]] = t[[4, 899, 69_999]] - 1.0  # steps back
    counts = sync.stamp_counts(t)
    step = np.diff(t)
    assert counts.unsorted == int(np.count_nonzero(step < 0)) == 3
    assert counts.repeated == int(np.count_nonzero(np.diff(np.sort(t)) == 0)) > 0
    idx = np.repeat(np.arange(1000), 3)
    assert sync.distinct_count(idx) == 1000
    assert sync.distinct_count(idx[::-1].copy()) == 1000


def test_aligned_distances_without_the_aligned_array() -> None:
    ref, est = _pair(2)
    m = sync.match(ref, est)
    for mode in ("se3", "sim3", "none", "yaw"):
        pair = aligned_pair(m.ref, m.est, mode, None, None)
        got = aligned_distances(pair)
        assert "est_xyz" not in pair.__dict__  # the (N, 3) aligned estimate was never built
        assert got.tobytes() == _distances(pair.est_xyz, pair.ref_xyz).tobytes()
    r = ape(ref, est, align="se3")
    assert r.errors.tobytes() == np.linalg.norm(r.est_xyz - r.ref_xyz, axis=1).tobytes()


def test_degrees_in_place_equal_degrees_of_radians() -> None:
    ref, est = _pair(3)
    deg = ape(ref, est, relation="angle_deg").errors
    rad = ape(ref, est, relation="angle_rad").errors
    assert deg.tobytes() == np.degrees(rad).tobytes()
    assert not np.shares_memory(deg, rad)
