"""Range-image feature extraction (LIO-SAM featureExtraction): smoothness from ranges,
occlusion and parallel-beam rejection, sectors per ring, edge and planar features."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from mrnc_eval.slam.config import FeatureConfig
from mrnc_eval.slam.range_image import RangeImage


@dataclass(frozen=True, kw_only=True)
class Features:
    edges: np.ndarray  # (Ne, 3) float64, sensor frame (deskewed); float32 once kept with a keyframe
    surfs: np.ndarray  # (Ns, 3)


@njit(cache=True, nogil=True)
def _mark_neighbours(picked: np.ndarray, col: np.ndarray, i: int) -> None:
    """A selected feature blocks its +/-5 neighbours on the ring, up to a column gap > 10."""
    n = picked.size
    picked[i] = True
    for k in range(1, 6):
        if i + k < n and abs(col[i + k] - col[i + k - 1]) <= 10:
            picked[i + k] = True
        else:
            break
    for k in range(1, 6):
        if i - k >= 0 and abs(col[i - k] - col[i - k + 1]) <= 10:
            picked[i - k] = True
        else:
            break


@njit(cache=True, nogil=True)
def _smoothness(rng: np.ndarray, xyz: np.ndarray, paper: bool) -> np.ndarray:
    """LIO-SAM's code: c = (sum of the 10 neighbour ranges - 10 r_i)^2 (m^2). The paper's formula
    (LOAM): c = |sum_u (p_i - p_u)| / (|S| |p_i|) over the same 10 neighbours (dimensionless; the
    edge/surf thresholds must then be chosen on that scale)."""
    n = rng.size
    curv = np.zeros(n)
    for i in range(5, n - 5):
        if paper:
            acc = 0.0
            for a in range(3):
                d = 10.0 * xyz[i, a]
                for k in range(1, 6):
                    d -= xyz[i - k, a] + xyz[i + k, a]
                acc += d * d
            norm = np.sqrt(xyz[i, 0] ** 2 + xyz[i, 1] ** 2 + xyz[i, 2] ** 2)
            curv[i] = np.sqrt(acc) / (10.0 * norm) if norm > 0 else 0.0
        else:
            d = -10.0 * rng[i]
            for k in range(1, 6):
                d += rng[i - k] + rng[i + k]
            curv[i] = d * d
    return curv


@njit(cache=True, nogil=True)
def _mark_occluded_and_parallel(rng: np.ndarray, col: np.ndarray, occ_jump: float, par_ratio: float) -> np.ndarray:
    """LIO-SAM's unreliable points: the far side of an occlusion (a range jump > occ_jump between
    neighbouring columns) and beams nearly parallel to the surface (both neighbours' ranges differ
    by more than par_ratio r)."""
    n = rng.size
    picked = np.zeros(n, np.bool_)
    for i in range(5, n - 6):  # occlusion
        if abs(col[i + 1] - col[i]) < 10:
            if rng[i] - rng[i + 1] > occ_jump:
                for k in range(i - 5, i + 1):
                    picked[k] = True
            elif rng[i + 1] - rng[i] > occ_jump:
                for k in range(i + 1, i + 7):
                    picked[k] = True
    for i in range(5, n - 6):  # parallel beams
        if abs(rng[i - 1] - rng[i]) > par_ratio * rng[i] and abs(rng[i + 1] - rng[i]) > par_ratio * rng[i]:
            picked[i] = True
    return picked


@njit(cache=True, nogil=True)
def _label_sector(sp: int, ep: int, curv: np.ndarray, col: np.ndarray, picked: np.ndarray, label: np.ndarray,
                  edge_thr: float, surf_thr: float, max_edges: int) -> None:
    """One sector [sp, ep]: the sharpest unpicked points above edge_thr become edges (at most
    max_edges), the flattest below surf_thr planes; each blocks its neighbours; every other
    non-edge point of the sector joins the planar cloud (label -2), as in LIO-SAM."""
    idx = np.argsort(curv[sp:ep + 1]) + sp
    count = 0
    for q in range(idx.size - 1, -1, -1):
        i = idx[q]
        if picked[i] or curv[i] <= edge_thr:
            continue
        count += 1
        if count > max_edges:
            break
        label[i] = 1
        _mark_neighbours(picked, col, i)
    for q in range(idx.size):
        i = idx[q]
        if picked[i] or curv[i] >= surf_thr:
            continue
        label[i] = -1
        _mark_neighbours(picked, col, i)
    for i in range(sp, ep + 1):
        if label[i] == 0:
            label[i] = -2


@njit(cache=True, nogil=True)
def _extract(rng: np.ndarray, curv: np.ndarray, col: np.ndarray, ring_start: np.ndarray, ring_end: np.ndarray,
             edge_thr: float, surf_thr: float, max_edges: int, sectors: int, occ_jump: float,
             par_ratio: float) -> np.ndarray:
    """Labels per point: 1 edge, -1 / -2 planar, 0 neither. Rings are split into `sectors` equal
    sectors so features spread around the sweep."""
    picked = _mark_occluded_and_parallel(rng, col, occ_jump, par_ratio)
    label = np.zeros(rng.size, np.int8)
    for r in range(ring_start.size):
        s, e = ring_start[r], ring_end[r]
        if e - s < 6 * sectors:
            continue
        for j in range(sectors):
            sp = (s * (sectors - j) + e * j) // sectors
            ep = (s * (sectors - 1 - j) + e * (j + 1)) // sectors - 1
            if sp < ep:
                _label_sector(sp, ep, curv, col, picked, label, edge_thr, surf_thr, max_edges)
    return label


@njit(cache=True, nogil=True)
def _voxel_centroids(points: np.ndarray, leaf: float) -> np.ndarray:
    """Open-addressing hash of packed voxel keys (21 bits per axis): O(N), first-seen order."""
    n = points.shape[0]
    cap, bits = 1, 0
    while cap < 2 * n:
        cap *= 2
        bits += 1
    table = np.full(cap, -1, np.int64)  # slot -> output index
    keys = np.empty(n, np.int64)
    sums = np.zeros((n, 3))
    counts = np.zeros(n, np.int64)
    m = 0
    for i in range(n):
        kx = np.int64(np.floor(points[i, 0] / leaf)) + (1 << 20)
        ky = np.int64(np.floor(points[i, 1] / leaf)) + (1 << 20)
        kz = np.int64(np.floor(points[i, 2] / leaf)) + (1 << 20)
        key = (kx << 42) | (ky << 21) | kz
        h = ((key * np.int64(-7046029254386353131)) >> (64 - bits)) & (cap - 1)  # Fibonacci hash: top bits
        while True:
            j = table[h]
            if j < 0:
                table[h] = m
                keys[m] = key
                j = m
                m += 1
                break
            if keys[j] == key:
                break
            h = (h + 1) & (cap - 1)
        sums[j, 0] += points[i, 0]
        sums[j, 1] += points[i, 1]
        sums[j, 2] += points[i, 2]
        counts[j] += 1
    out = np.empty((m, 3))
    for j in range(m):
        for a in range(3):
            out[j, a] = sums[j, a] / counts[j]
    return out


def voxel_downsample(points: np.ndarray, leaf: float) -> np.ndarray:
    """One point (the centroid) per voxel of size `leaf` (m), as PCL's VoxelGrid; voxel indices
    within +/-1e6 per axis."""
    if points.shape[0] == 0 or leaf <= 0:
        return points
    out: np.ndarray = _voxel_centroids(np.ascontiguousarray(points, dtype=np.float64), float(leaf))
    return out


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
    out: np.ndarray = _extract(rng, curv, image.column, starts + 5, starts + counts - 6, cfg.edge_threshold,
                               cfg.surf_threshold, cfg.max_edges_per_sector, cfg.sectors, cfg.occlusion_jump_m,
                               cfg.parallel_ratio)
    return out


def vertical_neighbours(image: RangeImage) -> np.ndarray:
    """(N, 2) int64: each point's neighbour in the same column on the ring above (row - 1) and
    below (row + 1) of the image, -1 where that pixel is empty; from the image layout alone."""
    n = len(image)
    if n == 0:
        return np.full((0, 2), -1, np.int64)
    out: np.ndarray = _vertical_neighbours(image.ring, image.column, int(image.ring.max()) + 1,
                                           int(image.column.max()) + 1)
    return out


@njit(cache=True, nogil=True)
def _vertical_neighbours(ring: np.ndarray, col: np.ndarray, rows: int, width: int) -> np.ndarray:
    grid = np.full((rows, width), -1, np.int64)
    for i in range(ring.size):
        grid[ring[i], col[i]] = i
    out = np.full((ring.size, 2), -1, np.int64)
    for i in range(ring.size):
        if ring[i] > 0:
            out[i, 0] = grid[ring[i] - 1, col[i]]
        if ring[i] + 1 < rows:
            out[i, 1] = grid[ring[i] + 1, col[i]]
    return out


@njit(cache=True, nogil=True)
def _flat_pair(points: np.ndarray, a: int, b: int, tan_max: float) -> bool:
    """`ground_mask`'s test of one pair, a on the upper ring and b below it, in the same arithmetic."""
    d0, d1, d2 = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1], points[b, 2] - points[a, 2]
    return bool(abs(d2) < tan_max * np.hypot(d0, d1) and points[a, 2] < 0 and points[b, 2] < 0)


@njit(cache=True, nogil=True)
def _ground_of(points: np.ndarray, candidates: np.ndarray, vertical: np.ndarray, tan_max: float) -> np.ndarray:
    """`ground_mask` at the `candidates` only: a point is ground when the pair with its upper or its
    lower neighbour is flat."""
    out = np.zeros(candidates.size, np.bool_)
    for q in range(candidates.size):
        i = candidates[q]
        up, down = vertical[i, 0], vertical[i, 1]
        out[q] = (up >= 0 and _flat_pair(points, up, i, tan_max)) or (down >= 0 and _flat_pair(points, i, down,
                                                                                                 tan_max))
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
