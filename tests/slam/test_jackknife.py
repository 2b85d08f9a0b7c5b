"""The block jackknife's helpers (slam/jackknife.py): blocks of equal information and the standard error."""

from __future__ import annotations

import numpy as np
import pytest

from mrnc_eval.slam.jackknife import equal_share_blocks, jackknife_sigma


def test_blocks_carry_equal_shares_of_the_weights_in_log_order() -> None:
    """A log still for its first half (weight 0) and moving for its second (weight 1), 5 blocks: the
    blocks are contiguous and each holds a fifth of the weight (10), the still half all in the first;
    equal-time blocks of 20 samples would hold 0, 0, 10, 20 and 20."""
    weights = np.r_[np.zeros(50), np.ones(50)]
    block = equal_share_blocks(weights, 5)
    assert np.all(np.diff(block) >= 0)
    assert np.bincount(block, weights=weights, minlength=5).tolist() == [10.0] * 5
    assert np.all(block[:50] == 0)


def test_blocks_of_equal_count_when_nothing_carries_weight() -> None:
    assert np.bincount(equal_share_blocks(np.zeros(40), 4)).tolist() == [10, 10, 10, 10]
    assert equal_share_blocks(np.zeros(0), 4).size == 0


def test_the_jackknife_of_a_mean_is_its_standard_error() -> None:
    """Closed form: the delete-one jackknife of a sample mean equals s / sqrt(n)."""
    x = np.random.default_rng(0).normal(3.0, 2.0, 25)
    replicates = (x.sum() - x) / (x.size - 1)
    assert jackknife_sigma(replicates) == pytest.approx(np.std(x, ddof=1) / np.sqrt(x.size), rel=1e-12)
    assert jackknife_sigma(np.array([1.0])) == float("inf")
