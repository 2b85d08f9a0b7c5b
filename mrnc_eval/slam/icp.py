"""Point-to-point ICP for loop closure, on the SLAM's own KD-tree (pykdtree, slam/nearest.py) and
the closed-form rigid fit of geometry/point_fit.py, so a SLAM run needs no open3d (209 MB resident
after import, ~0.9 GB on disk to read at a cold start).

Each iteration pairs every source point with its nearest target point closer than the maximum
correspondence distance, fits the rigid transform of those pairs (Umeyama without scale) and
applies it. It stops after `max_iterations`, when fewer than 3 pairs remain, or when both the inlier
fraction and the inlier RMSE change by less than their relative tolerances from one iteration to
the next (the usual ICP convergence rule: 1e-6 each in loop closure)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.errors import EvaluationError
from mrnc_eval.geometry import se3
from mrnc_eval.geometry.point_fit import umeyama
from mrnc_eval.slam.nearest import KdTree

MIN_PAIRS = 3  # a rigid fit needs three non-collinear pairs


@dataclass(frozen=True, kw_only=True)
class IcpResult:
    """The outcome of one ICP registration."""

    transform: NDArray[np.float64]  # 4x4, source -> target frame (includes the initial guess)
    fitness: float  # inlier fraction: pairs within the correspondence distance / source points
    inlier_rmse_m: float  # RMSE of those pairs' distances, m (inf without pairs)
    iterations: int  # rigid fits applied


def _pairs(tree: KdTree, moved: NDArray[np.float64], max_dist: float) -> tuple[NDArray[np.bool_], NDArray[np.int64],
                                                                                 float, float]:
    d, idx = tree.query(moved, k=1, max_dist=max_dist)
    hit = np.isfinite(d)
    n = int(hit.sum())
    fitness = n / len(moved) if len(moved) else 0.0
    rmse = float(np.sqrt(np.mean(d[hit] ** 2))) if n else float("inf")
    return hit, idx, fitness, rmse


def icp_point_to_point(source: NDArray[np.floating], target: NDArray[np.floating], max_correspondence_m: float,
                       initial: NDArray[np.float64], *, max_iterations: int, relative_fitness: float = 1e-6,
                       relative_rmse: float = 1e-6, tree: KdTree | None = None) -> IcpResult:
    """Align `source` (N, 3) onto `target` (M, 3) starting from `initial` (4x4); `tree` reuses a
    KD-tree already built on `target`."""
    src = np.asarray(source, np.float64)
    tgt = np.asarray(target, np.float64)
    tree = KdTree(tgt) if tree is None else tree
    T = np.array(initial, np.float64)
    moved = se3.apply(T, src)
    hit, idx, fitness, rmse = _pairs(tree, moved, max_correspondence_m)
    done = 0
    for _ in range(max_iterations):
        if hit.sum() < MIN_PAIRS:
            break
        try:
            r, t, _ = umeyama(moved[hit], tgt[idx[hit]], with_scale=False)
        except EvaluationError:  # collinear pairs: no unique rotation, keep the last transform
            break
        T = se3.make(r, t) @ T
        done += 1
        prev_fitness, prev_rmse = fitness, rmse
        moved = se3.apply(T, src)
        hit, idx, fitness, rmse = _pairs(tree, moved, max_correspondence_m)
        if abs(fitness - prev_fitness) < relative_fitness and abs(rmse - prev_rmse) < relative_rmse:
            break
    return IcpResult(transform=T, fitness=fitness, inlier_rmse_m=rmse, iterations=done)
