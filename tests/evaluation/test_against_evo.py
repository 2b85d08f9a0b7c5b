"""Our APE/RPE equal evo's to 1e-9 relative (sse 1e-12) on generated trajectories."""

from __future__ import annotations

import numpy as np
import pytest

from mrnc_eval.evaluation.ape import ape
from mrnc_eval.evaluation.rpe import rpe
from tests.evaluation.evo_reference import evo_ape, evo_rpe, make_pair

pytest.importorskip("evo")

RELATIONS = ["trans", "rot", "full", "angle_deg", "angle_rad", "point"]
ALIGNS = ["none", "se3", "sim3", "scale", "origin"]


def assert_stats_equal(ours: dict, theirs: dict, errors_ours, errors_theirs) -> None:
    np.testing.assert_allclose(errors_ours, errors_theirs, rtol=1e-9, atol=1e-12)
    for key in ("rmse", "mean", "median", "std", "min", "max"):
        assert ours[key] == pytest.approx(theirs[key], rel=1e-9, abs=1e-13), key
    assert ours["sse"] == pytest.approx(theirs["sse"], rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("align", ALIGNS)
@pytest.mark.parametrize("relation", RELATIONS)
def test_ape_equals_evo(align: str, relation: str) -> None:
    ref, est = make_pair(seed=hash((align, relation)) % 1000)
    ours = ape(ref, est, align=align, relation=relation, max_diff=0.01, offset=-0.003)
    theirs, err = evo_ape(ref, est, relation=relation, align=align, max_diff=0.01, offset=-0.003)
    assert ours.n == err.size
    assert_stats_equal(ours.stats, theirs, ours.errors, err)


@pytest.mark.parametrize("align", ["se3", "sim3"])
def test_ape_first_n_and_plane_equal_evo(align: str) -> None:
    ref, est = make_pair(seed=3)
    ours = ape(ref, est, align=align, n_to_align=100, plane="xy")
    theirs, err = evo_ape(ref, est, relation="trans", align=align, n_to_align=100, plane="xy")
    assert_stats_equal(ours.stats, theirs, ours.errors, err)


@pytest.mark.parametrize("relation", RELATIONS)
@pytest.mark.parametrize("delta, unit, all_pairs", [(1, "frames", False), (7, "frames", True),
                                                    (1.0, "m", False), (2.5, "m", True)])
def test_rpe_equals_evo(relation: str, delta: float, unit: str, all_pairs: bool) -> None:
    ref, est = make_pair(seed=11)
    ours = rpe(ref, est, delta=delta, delta_unit=unit, all_pairs=all_pairs, relation=relation, align="se3")
    theirs, err = evo_rpe(ref, est, relation=relation, delta=delta, unit=unit, all_pairs=all_pairs, align="se3")
    assert ours.n == err.size
    assert_stats_equal(ours.stats, theirs, ours.errors, err)


def test_rpe_pairs_from_reference_equals_evo() -> None:
    ref, est = make_pair(seed=5)
    ours = rpe(ref, est, delta=1.0, delta_unit="m", relation="trans", pairs_from="reference", align="sim3")
    theirs, err = evo_rpe(ref, est, relation="trans", delta=1.0, unit="m", align="sim3", pairs_from_reference=True)
    assert_stats_equal(ours.stats, theirs, ours.errors, err)
