"""Loop closure's point-to-point ICP (slam/icp.py) without open3d: it recovers a known rigid motion
of a structured cloud, agrees with open3d's ICP on the same input, and fails when the pairs it may
use cannot reach (the negative control)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mrnc_eval.geometry import se3
from mrnc_eval.slam.config import LoopConfig
from mrnc_eval.slam.graph import register_loop
from mrnc_eval.slam.icp import icp_point_to_point

MOTION = se3.make(Rotation.from_euler("xyz", [1.0, -2.0, 6.0], degrees=True).as_matrix(), np.array([0.35, -0.2, 0.1]))


def _scene(seed: int = 0) -> np.ndarray:
    """A floor, two walls at an angle and a few tree trunks: a cloud that pins all six degrees of freedom."""
    rng = np.random.default_rng(seed)
    floor = np.c_[rng.uniform(-10, 10, (3000, 2)), rng.normal(0, 0.01, 3000)]
    wall_a = np.c_[rng.uniform(-10, 10, 1500), np.full(1500, 8.0), rng.uniform(0, 4, 1500)]
    wall_b = np.c_[np.full(1500, -7.0), rng.uniform(-10, 10, 1500), rng.uniform(0, 4, 1500)]
    angle = rng.uniform(0, 2 * np.pi, 2000)
    centres = rng.uniform(-6, 6, (8, 2))[rng.integers(0, 8, 2000)]
    trunks = np.c_[centres + 0.3 * np.c_[np.cos(angle), np.sin(angle)], rng.uniform(0, 5, 2000)]
    return np.vstack([floor, wall_a, wall_b, trunks])


def _error(T: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Translation (m) and rotation (deg) between two poses."""
    d = se3.inv(truth) @ T
    return float(np.linalg.norm(d[:3, 3])), float(np.degrees(se3.delta_angle(d)))


def test_icp_recovers_a_known_motion() -> None:
    target = _scene()
    source = se3.apply(se3.inv(MOTION), target[::2])  # the same surfaces seen from a moved pose
    res = icp_point_to_point(source, target, 2.0, np.eye(4), max_iterations=100)
    dt, dr = _error(res.transform, MOTION)
    assert dt < 1e-9, dt  # exact points: measured 1e-14 m and 1e-14 deg, in 11 iterations
    assert dr < 1e-9, dr
    assert res.fitness == pytest.approx(1.0)
    assert res.inlier_rmse_m < 1e-3
    assert 1 < res.iterations < 100  # converged by the relative-change rule, not by the iteration cap


def test_icp_cannot_recover_when_pairs_cannot_reach() -> None:
    """Negative control: with a maximum correspondence distance far below the motion (0.4 m)
    almost nothing pairs and the result stays near the initial guess, far from the truth
    (measured: no fit at all, 0.05 % paired)."""
    target = _scene()
    source = se3.apply(se3.inv(MOTION), target[::2])
    res = icp_point_to_point(source, target, 0.02, np.eye(4), max_iterations=100)
    dt, _ = _error(res.transform, MOTION)
    assert dt > 0.2
    assert res.fitness < 0.2


def test_icp_agrees_with_open3d_on_noisy_partial_clouds() -> None:
    o3d = pytest.importorskip("open3d")  # the slam extra installs it (for the simulator)
    rng = np.random.default_rng(4)
    target = _scene(1)
    source = se3.apply(se3.inv(MOTION), target[rng.random(len(target)) < 0.4]) + rng.normal(0, 0.02, (1, 3))
    source = source + rng.normal(0, 0.02, source.shape)
    ours = icp_point_to_point(source, target, 1.0, np.eye(4), max_iterations=100)
    reg = o3d.pipelines.registration
    theirs = reg.registration_icp(o3d.geometry.PointCloud(o3d.utility.Vector3dVector(source)),
                                  o3d.geometry.PointCloud(o3d.utility.Vector3dVector(target)), 1.0, np.eye(4),
                                  reg.TransformationEstimationPointToPoint(),
                                  reg.ICPConvergenceCriteria(relative_fitness=1e-6, relative_rmse=1e-6,
                                                             max_iteration=100))
    dt, dr = _error(ours.transform, np.asarray(theirs.transformation))
    # the same pairs and fits, so the same result to rounding (measured 5e-15 m, 2e-14 deg, 12 iterations)
    assert dt < 1e-9, dt
    assert dr < 1e-9, dr
    assert ours.fitness == theirs.fitness
    assert ours.inlier_rmse_m == pytest.approx(theirs.inlier_rmse, rel=1e-9)


def test_register_loop_contract() -> None:
    """Correction, PCL fitness and converged: a good guess-free loop is accepted, a source far
    beyond both stages' reach is reported as not converged."""
    target = _scene()
    source = se3.apply(se3.inv(MOTION), target[::3])
    T, fitness, ok = register_loop(source, target, np.eye(4), LoopConfig())
    assert ok
    assert fitness < 1e-6
    assert _error(T, MOTION)[0] < 1e-3
    far = source + np.array([500.0, 0.0, 0.0])  # beyond the 30 m first stage
    _, fitness_far, ok_far = register_loop(far, target, np.eye(4), LoopConfig())
    assert not ok_far
    assert fitness_far == float("inf")
