"""Range-image feature extraction (LIO-SAM featureExtraction): smoothness from ranges,
occlusion and parallel-beam rejection, sectors per ring, edge and planar features."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrnc_eval.slam import _prep_kernels
from mrnc_eval.slam.config import FeatureConfig
from mrnc_eval.slam.range_image import RangeImage


@dataclass(frozen=True, kw_only=True)
class Features:
    """A sweep's edge and plane features."""

    edges: np.ndarray  # (Ne, 3) float64, sensor frame (deskewed); float32 once kept with a keyframe
    surfs: np.ndarray  # (Ns, 3)


def _smoothness(rng: np.ndarray, xyz: np.ndarray, paper: bool) -> np.ndarray:
    """LIO-SAM's code: c = (sum of the 10 neighbour ranges - 10 r_i)^2 (m^2). The paper's formula
    (LOAM): c = |sum_u (p_i - p_u)| / (|S| |p_i|) over the same 10 neighbours (dimensionless; the
    edge/surf thresholds must then be chosen on that scale). 0 for the 5 points at either end."""
    curv = np.empty(len(rng))
    _prep_kernels.smoothness(np.ascontiguousarray(rng, dtype=np.float64), np.ascontiguousarray(xyz, dtype=np.float64),
                             paper, curv)
    return curv


def voxel_downsample(points: np.ndarray, leaf: float) -> np.ndarray:
    """One point (the centroid) per voxel of size `leaf` (m), as PCL's VoxelGrid; voxel indices
    within +/-1e6 per axis."""
    if points.shape[0] == 0 or leaf <= 0:
        return points
    # an open-addressing hash of packed voxel keys: O(N), first-seen order (slam/_prep_kernels.c)
    out = _prep_kernels.voxel_centroids(np.ascontiguousarray(points, dtype=np.float64), float(leaf))
    return np.frombuffer(out, np.float64).reshape(-1, 3)


def ground_mask(image: RangeImage, points: np.ndarray, max_angle_deg: float) -> np.ndarray:
    """LeGO-LOAM's ground test: a point below the sensor whose segment to the same column's point
    on the next ring rises less than max_angle_deg is ground. (N,) bool."""
    n = len(image)
    ground = np.zeros(n, bool)
    if n == 0 or max_angle_deg <= 0:
        return ground
    grid = np.full((int(image.ring.max()) + 1, int(image.column.max()) + 1), -1, np.int64)
    grid[image.ring, image.column] = np.arange(n)
    a, b = grid[:-1].ravel(), grid[1:].ravel()
    pair = (a >= 0) & (b >= 0)
    a, b = a[pair], b[pair]
    d = points[b] - points[a]
    flat = np.abs(d[:, 2]) < np.tan(np.radians(max_angle_deg)) * np.hypot(d[:, 0], d[:, 1])
    flat &= (points[a, 2] < 0) & (points[b, 2] < 0)
    ground[a[flat]] = True
    ground[b[flat]] = True
    return ground


def feature_labels(image: RangeImage, points: np.ndarray | None, cfg: FeatureConfig) -> np.ndarray:
    """Labels per point of the ring-major image: 1 edge candidate, -1 / -2 planar, 0 neither.
    With smoothness "range" (LIO-SAM's code) they depend on the ranges and columns alone, so they
    can be computed before the sweep is deskewed (slam/sweep_prep.py: ahead, in another thread);
    "paper" needs the deskewed `points`."""
    ring, rng = image.ring, image.range_m
    starts = np.flatnonzero(np.r_[True, ring[1:] != ring[:-1]])
    counts = np.diff(np.r_[starts, ring.size])
    xyz = image.points if points is None else points
    curv = _smoothness(rng, xyz, cfg.smoothness == "paper")
    # LIO-SAM's unreliable points (occlusions, beams parallel to the surface) blocked, then each ring in
    # cfg.sectors equal sectors: the sharpest points above edge_threshold edges (at most
    # max_edges_per_sector), the flattest below surf_threshold planes, each blocking its +/-5 neighbours
    out = np.empty(ring.size, np.int8)
    _prep_kernels.extract(np.ascontiguousarray(rng, dtype=np.float64), curv, _int64(image.column),
                          _int64(starts + 5), _int64(starts + counts - 6), float(cfg.edge_threshold),
                          float(cfg.surf_threshold), int(cfg.max_edges_per_sector), int(cfg.sectors),
                          float(cfg.occlusion_jump_m), float(cfg.parallel_ratio), out)
    return out


def _int64(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.int64)


def vertical_neighbours(image: RangeImage) -> np.ndarray:
    """(N, 2) int64: each point's neighbour in the same column on the ring above (row - 1) and
    below (row + 1) of the image, -1 where that pixel is empty; from the image layout alone."""
    n = len(image)
    if n == 0:
        return np.full((0, 2), -1, np.int64)
    ring, column = _int64(image.ring), _int64(image.column)
    out = np.empty((n, 2), np.int64)
    _prep_kernels.vertical_neighbours(ring, column, int(ring.max()) + 1, int(column.max()) + 1, out)
    return out


def _ground_of(points: np.ndarray, candidates: np.ndarray, vertical: np.ndarray, tan_max: float) -> np.ndarray:
    """`ground_mask` at the `candidates` only, in the same arithmetic: a point is ground when the pair
    with its upper or its lower neighbour is flat."""
    out = np.empty(len(candidates), bool)
    _prep_kernels.ground_of(np.ascontiguousarray(points, dtype=np.float64), _int64(candidates), _int64(vertical),
                            float(tan_max), out)
    return out


def extract_features(image: RangeImage, points: np.ndarray, cfg: FeatureConfig, *, labels: np.ndarray | None = None,
                     vertical: np.ndarray | None = None) -> Features:
    """Edges and planes of one sweep. `image` gives the ring-major order and the (raw) ranges,
    `points` (N, 3) the same points deskewed. `labels` (`feature_labels`) and `vertical`
    (`vertical_neighbours`), when given, were computed ahead from the image alone."""
    if len(image) < 12:
        return Features(edges=np.zeros((0, 3)), surfs=np.zeros((0, 3)))
    if labels is None:
        labels = feature_labels(image, points, cfg)
    edge_idx = np.flatnonzero(labels == 1)
    if cfg.ground_max_angle_deg > 0:  # ground rings are smooth arcs: their "edges" are roughness and noise
        if vertical is None:
            vertical = vertical_neighbours(image)
        tan_max = float(np.tan(np.radians(cfg.ground_max_angle_deg)))
        edge_idx = edge_idx[~_ground_of(points, edge_idx, vertical, tan_max)]
    edges = points[edge_idx]
    surfs = voxel_downsample(points[labels < 0], cfg.surf_leaf_m)
    return Features(edges=edges, surfs=surfs)
