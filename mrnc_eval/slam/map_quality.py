"""Map quality without ground truth (Razlaw et al. 2015, "Evaluation of registration methods
for sparse 3D laser scans"): for each evaluated map point, the covariance of the map points
within a radius r.

- mean map entropy (MME): mean over points of h = 0.5 ln det(2 pi e Sigma), in nats; a sharper
  (better registered) map has smaller, more negative entropy.
- mean plane variance (MPV): mean over points of the smallest eigenvalue of Sigma, m^2: the
  spread of the neighbourhood across its best-fitting plane (blurred surfaces raise it).

Neighbourhoods are the nearest `max_neighbours` points within r (one KD-tree query); points
with fewer than `min_neighbours` are skipped. Both are comparable only between runs with the
same radius and map resolution."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrnc_eval.slam.nearest import KdTree


@dataclass(frozen=True, kw_only=True)
class MapQuality:
    """How crisp the map is: entropy and plane variance."""

    mean_map_entropy: float  # nats
    mean_plane_variance_m2: float
    points_evaluated: int


def map_quality(points: np.ndarray, radius_m: float, *, min_neighbours: int = 5, max_neighbours: int = 30,
                max_points: int = 10000) -> MapQuality | None:
    """MME and MPV of `points` (N, 3, m), evaluated at up to `max_points` evenly strided points."""
    if points.shape[0] < min_neighbours:
        return None
    queries = points[np.unique(np.linspace(0, points.shape[0] - 1, min(max_points, points.shape[0])).astype(int))]
    k = min(max_neighbours, points.shape[0])
    d, idx = KdTree(points).query(queries, k=k, max_dist=radius_m)
    inside = np.isfinite(d)
    keep = inside.sum(axis=1) >= min_neighbours
    if not keep.any():
        return None
    nb = points[np.where(inside[keep], idx[keep], 0)]  # (m, k, 3); outside the radius masked below
    w = inside[keep][:, :, None].astype(np.float64)
    n = w.sum(axis=1)
    mean = (nb * w).sum(axis=1) / n
    c = (nb - mean[:, None, :]) * w
    cov = np.einsum("nki,nkj->nij", c, c) / n[:, :, None]
    eig = np.linalg.eigvalsh(cov)
    det = np.prod(np.clip(eig, 0.0, None), axis=1)
    finite = det > 0
    entropy = 0.5 * np.log((2 * np.pi * np.e) ** 3 * det[finite])
    return MapQuality(mean_map_entropy=float(entropy.mean()) if finite.any() else float("nan"),
                      mean_plane_variance_m2=float(eig[:, 0].mean()),
                      points_evaluated=int(keep.sum()))
