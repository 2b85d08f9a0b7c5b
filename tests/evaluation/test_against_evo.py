"""Our APE/RPE equal evo's to 1e-9 relative (sse 1e-12) on generated trajectories."""

from __future__ import annotations

import copy
import zlib

import numpy as np
import pytest

from mrnc_eval.evaluation.ape import ape
from mrnc_eval.evaluation.rpe import rpe
from tests.evaluation.evo_reference import evo_ape, evo_rpe, make_pair, require_evo

require_evo()

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
    ref, est = make_pair(seed=zlib.crc32(f"{align}/{relation}".encode()) % 1000)  # stable across runs
    ours = ape(ref, est, align=align, relation=relation, max_diff=0.01, offset=-0.003)
    theirs, err = evo_ape(ref, est, relation=relation, align=align, max_diff=0.01, offset=-0.003)
    assert ours.n == err.size
    assert_stats_equal(ours.stats, theirs, ours.errors, err)


@pytest.mark.parametrize("align", ["se3", "sim3", "scale"])
@pytest.mark.parametrize("plane", ["xy", "xz", "yz"])
@pytest.mark.parametrize("relation", ["trans", "full", "angle_deg"])
def test_ape_first_n_and_plane_equal_evo(align: str, plane: str, relation: str) -> None:
    ref, est = make_pair(seed=3)
    ours = ape(ref, est, align=align, n_to_align=100, plane=plane, relation=relation)
    theirs, err = evo_ape(ref, est, relation=relation, align=align, n_to_align=100, plane=plane)
    assert_stats_equal(ours.stats, theirs, ours.errors, err)


def test_aligned_poses_and_transform_equal_evo() -> None:
    """The aligned estimate itself (not only the statistics) and the Sim(3) transform, both
    against evo: its projected poses, and the rotation, translation and scale its align returns."""
    from evo.core import sync

    from tests.evaluation.evo_reference import evo_prepare, to_evo

    ref, est = make_pair(seed=8)
    ours = ape(ref, est, align="sim3", plane="xy")
    r, e = evo_prepare(ref, est, align="sim3", max_diff=0.01, offset=0.0, n_to_align=None, plane="xy")
    np.testing.assert_allclose(ours.est_poses, np.array(e.poses_se3), atol=1e-12)
    np.testing.assert_allclose(ours.ref_poses, np.array(r.poses_se3), atol=1e-12)

    ours = ape(ref, est, align="sim3")
    r_evo, e_evo = sync.associate_trajectories(to_evo(ref), to_evo(est), max_diff=0.01)
    e_evo = copy.deepcopy(e_evo)
    rot, trans, scale = e_evo.align(r_evo, correct_scale=True)
    evo_sim3 = np.eye(4)
    evo_sim3[:3, :3], evo_sim3[:3, 3] = scale * rot, trans
    assert abs(scale - 1.0) > 0.01  # the estimate is built 5 % too large: the scale is really tested
    assert ours.scale == pytest.approx(scale, rel=1e-12)
    np.testing.assert_allclose(ours.transform, evo_sim3, atol=1e-12)
    np.testing.assert_allclose(ours.est_aligned.positions, e_evo.positions_xyz, atol=1e-12)
    np.testing.assert_allclose(ours.est_poses, np.array(e_evo.poses_se3), atol=1e-12)


@pytest.mark.parametrize("relation", RELATIONS)
@pytest.mark.parametrize(("delta", "unit", "all_pairs"), [(1, "frames", False), (7, "frames", True),
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


@pytest.mark.parametrize("n_to_align", [100, None])
def test_umeyama_is_bit_identical_to_evo(n_to_align: int | None) -> None:
    """Over the first 100 poses the path is nearly straight: the SVD amplifies any change of
    summation order ~1e4-fold, so only evo's operation order gives the same R, t, c."""
    from evo.core import geometry

    from mrnc_eval.evaluation.align import umeyama
    from mrnc_eval.evaluation.ape import matched_pair
    from tests.evaluation.evo_reference import evo_prepare

    ref, est = make_pair(seed=0, n=3000)
    r, e = evo_prepare(ref, est, align="none", max_diff=0.01, offset=0.0, n_to_align=None, plane=None)
    ref_m, est_m = matched_pair(ref, est, max_diff=0.01, offset=0.0)
    n = n_to_align or len(ref_m)
    ours = umeyama(est_m.positions[:n], ref_m.positions[:n], with_scale=True)
    theirs = geometry.umeyama_alignment(e.positions_xyz[:n].T, r.positions_xyz[:n].T, True)
    for a, b in zip(ours, theirs, strict=False):
        np.testing.assert_array_equal(a, b)
