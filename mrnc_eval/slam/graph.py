"""Keyframe factor graph (LIO-SAM graph #1) on gtsam iSAM2 with QR factorisation: prior,
odometry between-factors (T_i^-1 T_{i+1}), GNSS factors gated on pose uncertainty, and
loop-closure factors checked by ICP (fitness = mean squared nearest-neighbour distance)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mrnc_eval.errors import ProcessingError
from mrnc_eval.geometry import se3
from mrnc_eval.slam.config import GraphConfig, LoopConfig
from mrnc_eval.slam.icp import icp_point_to_point
from mrnc_eval.slam.nearest import KdTree


@dataclass(kw_only=True)
class KeyframeGraph:
    """The keyframes and their factor graph."""

    cfg: GraphConfig
    poses: list[np.ndarray] = field(default_factory=list)  # optimised keyframe poses (4x4)
    stamps: list[float] = field(default_factory=list)
    loops: list[tuple[int, int, float]] = field(default_factory=list)  # (current, previous, fitness)
    gps_factors: int = 0
    wheel_factors: int = 0
    last_gps_xy: np.ndarray | None = None
    anchored: bool = False  # the first keyframe's prior: cfg.anchored_prior_variances, else cfg.prior_variances

    def __post_init__(self) -> None:
        import gtsam

        self.gtsam = gtsam
        params = gtsam.ISAM2Params()
        params.setRelinearizeThreshold(self.cfg.relinearize_threshold)
        params.relinearizeSkip = self.cfg.relinearize_skip
        params.setFactorization(self.cfg.factorization)
        self.isam = gtsam.ISAM2(params)

    def _noise(self, variances: Sequence[float] | np.ndarray) -> Any:
        return self.gtsam.noiseModel.Diagonal.Variances(np.asarray(variances, float))

    def add_keyframe(self, pose: np.ndarray, stamp: float, loose_directions: np.ndarray | None = None,
                     wheel: tuple[np.ndarray, np.ndarray] | None = None, wheel_loose_sigma: float = 0.0) -> np.ndarray:
        """Add a keyframe with its scan-to-map pose; returns the optimised pose. `loose_directions`
        (k, 6): directions ([rot, trans], map axes) the match left to the IMU; the odometry factor
        gets degenerate_odometry_sigma along them (wheel_loose_sigma when that is 0 and a wheel
        factor comes). `wheel`: (relative pose from the previous keyframe, 6x6 covariance [rot, trans])."""
        g = self.gtsam
        graph, values = g.NonlinearFactorGraph(), g.Values()
        k = len(self.poses)
        if k == 0:
            prior = self.cfg.anchored_prior_variances if self.anchored else self.cfg.prior_variances
            graph.add(g.PriorFactorPose3(k, g.Pose3(pose), self._noise(prior)))
        else:
            rel = se3.inv(self.poses[-1]) @ pose
            sigma = self.cfg.degenerate_odometry_sigma or (wheel_loose_sigma if wheel is not None else 0.0)
            graph.add(g.BetweenFactorPose3(k - 1, k, g.Pose3(rel), self._odometry_noise(pose, loose_directions, sigma)))
            if wheel is not None:
                graph.add(g.BetweenFactorPose3(k - 1, k, g.Pose3(wheel[0]), g.noiseModel.Gaussian.Covariance(wheel[1])))
                self.wheel_factors += 1
        values.insert(k, g.Pose3(pose))
        self.poses.append(pose)
        self.stamps.append(stamp)
        self._update(graph, values, extra=0)
        return self.poses[-1]

    def _odometry_noise(self, pose: np.ndarray, loose: np.ndarray | None, sigma: float) -> Any:
        if loose is None or len(loose) == 0 or sigma <= 0:
            return self._noise(self.cfg.odometry_variances)
        u = loose @ np.kron(np.eye(2), pose[:3, :3])  # map axes -> the new keyframe's frame (gtsam's tangent)
        cov = np.diag(self.cfg.odometry_variances) + sigma ** 2 * (u.T @ u)
        return self.gtsam.noiseModel.Gaussian.Covariance(cov)

    def add_loop(self, cur: int, prev: int, relative: np.ndarray, fitness: float) -> None:
        g = self.gtsam
        graph = g.NonlinearFactorGraph()
        graph.add(g.BetweenFactorPose3(prev, cur, g.Pose3(relative), self._noise([fitness] * 6)))
        self.loops.append((cur, prev, fitness))
        self._update(graph, g.Values(), extra=self.cfg.extra_updates)

    def add_gps(self, k: int, position: np.ndarray, variances: np.ndarray, lever_arm: np.ndarray | None = None,
                floor_m2: float = 1.0, huber_k: float = 0.0) -> None:
        """GNSS position (map frame) of the antenna at `lever_arm` in the LiDAR frame of keyframe k;
        variances floored at floor_m2 (LIO-SAM: 1 m^2); a Huber kernel of width huber_k sigmas when > 0."""
        g = self.gtsam
        graph = g.NonlinearFactorGraph()
        noise = self._noise(np.maximum(variances, floor_m2))
        if huber_k > 0:
            noise = g.noiseModel.Robust.Create(g.noiseModel.mEstimator.Huber.Create(huber_k), noise)
        if lever_arm is not None and np.any(lever_arm != 0):
            graph.add(g.GPSFactorArm(k, np.asarray(position, float), np.asarray(lever_arm, float), noise))
        else:
            graph.add(g.GPSFactor(k, g.Point3(*position), noise))
        self.gps_factors += 1
        self.last_gps_xy = np.asarray(position[:2], float).copy()
        self._update(graph, g.Values(), extra=self.cfg.extra_updates)

    def xy_variance(self) -> float:
        cov = self.isam.marginalCovariance(len(self.poses) - 1)  # [rot, trans]
        return float(max(cov[3, 3], cov[4, 4]))

    def _update(self, graph: Any, values: Any, extra: int) -> None:
        try:
            self.isam.update(graph, values)
            self.isam.update()
            for _ in range(extra):
                self.isam.update()
            est = self.isam.calculateEstimate()
        except RuntimeError as err:  # gtsam reports an indeterminate system this way
            raise ProcessingError(f"factor graph update failed at keyframe {len(self.poses) - 1}: {err}") from err
        self.poses = [est.atPose3(i).matrix() for i in range(len(self.poses))]


def icp_fitness(source: np.ndarray, target: np.ndarray, max_dist: float) -> float:
    """PCL's fitness score: mean squared distance to the nearest target point (within max_dist)."""
    return _fitness(KdTree(target), source, max_dist)


def _fitness(tree: KdTree, source: np.ndarray, max_dist: float) -> float:
    d, _ = tree.query(source, k=1, max_dist=max_dist)
    d = d[np.isfinite(d)]
    return float(np.mean(d * d)) if d.size else float("inf")


def icp_min_eigenvalue(source: np.ndarray, target: np.ndarray, origin: np.ndarray, ground_normal_min_z: float,
                       max_dist: float = 1.0, k: int = 8) -> float:
    """How well the aligned clouds pin all six degrees of freedom: the smallest eigenvalue of
    J^T J of point-to-plane rows [(p - origin) x n, n], n = the normal of the target's k nearest
    points around each source point's nearest target point (within max_dist), with scan-to-map's
    ground split (ground rows: z, roll, pitch only). Flat ground alone gives ~0: ICP then slides
    freely in x, y and yaw and its low fitness says nothing."""
    tree = KdTree(target)
    d, nearest = tree.query(source, k=1, max_dist=max_dist)
    hit = np.isfinite(d)
    if hit.sum() < 6:
        return 0.0
    _, nb = tree.query(target[nearest[hit]], k=k)
    patch = target[nb] - target[nb].mean(axis=1, keepdims=True)
    _, vec = np.linalg.eigh(np.einsum("nki,nkj->nij", patch, patch))
    n = vec[:, :, 0]  # smallest-eigenvalue eigenvector: the patch normal
    J = np.c_[np.cross(source[hit] - origin, n), n]
    if ground_normal_min_z > 0:
        J[np.ix_(np.abs(n[:, 2]) > ground_normal_min_z, [2, 3, 4])] = 0.0
    return float(np.linalg.eigvalsh(J.T @ J)[0])


def loop_candidate(graph: KeyframeGraph, cfg: LoopConfig) -> int | None:
    cur = len(graph.poses) - 1
    if cur < 1 or any(c == cur for c, _, _ in graph.loops):
        return None
    pos = np.array([p[:3, 3] for p in graph.poses])
    d = np.linalg.norm(pos - pos[cur], axis=1)
    t = np.asarray(graph.stamps)
    ok = np.flatnonzero((d < cfg.search_radius_m) & (t[cur] - t > cfg.time_gap_s))
    return int(ok[np.argmin(d[ok])]) if ok.size else None


def register_loop(src: np.ndarray, tgt: np.ndarray, guess: np.ndarray,
                  cfg: LoopConfig) -> tuple[np.ndarray, float, bool]:
    """Point-to-point ICP (slam/icp.py) of the current keyframe cloud onto the submap, both in the
    map frame: from `guess` within cfg.icp_max_correspondence_m, then refined within 1 m; returns
    the correction, the PCL-style fitness and whether the refined ICP kept any pairs."""
    tree = KdTree(tgt)  # one tree for both stages and the fitness
    coarse = icp_point_to_point(src, tgt, cfg.icp_max_correspondence_m, guess, max_iterations=cfg.icp_iterations,
                                tree=tree)
    res = icp_point_to_point(src, tgt, 1.0, coarse.transform, max_iterations=cfg.icp_iterations, tree=tree)
    T = res.transform
    fitness = _fitness(tree, se3.apply(T, src), cfg.icp_max_correspondence_m)
    return T, fitness, bool(res.fitness > 0)
