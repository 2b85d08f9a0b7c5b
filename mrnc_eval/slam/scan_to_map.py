"""Scan-to-map matching (LIO-SAM mapOptimization): point-to-line and point-to-plane
residuals against a local map, Gauss-Newton with degeneracy remapping."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from mrnc_eval.slam import se3
from mrnc_eval.slam.config import MatchingConfig


@dataclass
class LocalMap:
    edges: np.ndarray
    surfs: np.ndarray
    edge_tree: cKDTree | None
    surf_tree: cKDTree | None

    @classmethod
    def build(cls, edges: np.ndarray, surfs: np.ndarray) -> LocalMap:
        return cls(edges, surfs, cKDTree(edges) if len(edges) >= 5 else None, cKDTree(surfs) if len(surfs) >= 5 else None)


@dataclass(frozen=True)
class MatchResult:
    pose: np.ndarray  # 4x4 sensor pose in the map
    iterations: int
    converged: bool
    degenerate: bool
    min_eigenvalue: float
    n_edges: int
    n_surfs: int
    optimised: bool
    n_degenerate: int = 0  # directions projected out


def _skew_cross_rows(q: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Jacobian rows of r = n . (R p + t) w.r.t. a left rotation perturbation: q x n (q = R p)."""
    return np.cross(q, n)


def _plane_terms(q, surf_map: LocalMap, workers: int, max_sq: float):
    d, idx = surf_map.surf_tree.query(q, k=5, workers=workers)
    ok = d[:, 4] < max_sq ** 0.5
    if not ok.any():
        return np.zeros((0, 6)), np.zeros(0)
    q, nb = q[ok], surf_map.surfs[idx[ok]]  # (m, 5, 3)
    # plane A n = -1 by least squares per point (batched normal equations)
    AtA = np.einsum("mki,mkj->mij", nb, nb)
    Atb = -nb.sum(axis=1)
    try:
        normal = np.linalg.solve(AtA + 1e-9 * np.eye(3), Atb[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return np.zeros((0, 6)), np.zeros(0)
    norm = np.linalg.norm(normal, axis=1)
    good = norm > 1e-9
    normal, nb, q, norm = normal[good], nb[good], q[good], norm[good]
    normal /= norm[:, None]
    dist = 1.0 / norm
    planar = np.all(np.abs(np.einsum("mkj,mj->mk", nb, normal) + dist[:, None]) <= 0.2, axis=1)
    normal, q, dist = normal[planar], q[planar], dist[planar]
    pd = np.einsum("mj,mj->m", normal, q) + dist
    s = 1.0 - 0.9 * np.abs(pd) / np.sqrt(np.linalg.norm(q, axis=1) + 1e-9)
    use = s > 0.1
    J = np.c_[_skew_cross_rows(q[use], normal[use]), normal[use]] * s[use, None]
    return J, pd[use] * s[use]


def _edge_terms(q, edge_map: LocalMap, workers: int, max_sq: float):
    d, idx = edge_map.edge_tree.query(q, k=5, workers=workers)
    ok = d[:, 4] < max_sq ** 0.5
    if not ok.any():
        return np.zeros((0, 6)), np.zeros(0)
    q, nb = q[ok], edge_map.edges[idx[ok]]
    c = nb.mean(axis=1)
    cov = np.einsum("mki,mkj->mij", nb - c[:, None], nb - c[:, None]) / 5.0
    w, v = np.linalg.eigh(cov)
    line = w[:, 2] > 3.0 * w[:, 1]
    q, c, u = q[line], c[line], v[line, :, 2]
    diff = q - c
    perp = diff - np.einsum("mj,mj->m", diff, u)[:, None] * u  # vector from the line to the point
    ld = np.linalg.norm(perp, axis=1)
    s = 1.0 - 0.9 * ld
    use = (s > 0.1) & (ld > 1e-9)
    n = perp[use] / ld[use, None]  # residual = n . (q - c) = distance to the line
    J = np.c_[_skew_cross_rows(q[use], n), n] * s[use, None]
    return J, ld[use] * s[use]


def match(edges: np.ndarray, surfs: np.ndarray, local_map: LocalMap, guess: np.ndarray, cfg: MatchingConfig) -> MatchResult:
    """Refine `guess` (4x4) so the sweep's features lie on the map's lines and planes."""
    if (len(edges) < cfg.min_edges or len(surfs) < cfg.min_surfs or local_map.surf_tree is None
            or local_map.edge_tree is None):
        return MatchResult(guess, 0, False, False, float("nan"), len(edges), len(surfs), False)
    T = guess.copy()
    P = np.eye(6)
    degenerate, min_eig, converged, it, n_bad = False, float("nan"), False, 0, 0
    for it in range(1, cfg.max_iterations + 1):
        Je, re = _edge_terms(se3.apply(T, edges), local_map, cfg.kdtree_workers, cfg.max_nn_sq_dist_m2)
        Js, rs = _plane_terms(se3.apply(T, surfs), local_map, cfg.kdtree_workers, cfg.max_nn_sq_dist_m2)
        J, r = np.r_[Je, Js], np.r_[re, rs]
        if r.size < cfg.min_correspondences:
            break
        H = J.T @ J
        g = -J.T @ r
        dx = np.linalg.lstsq(H, g, rcond=None)[0]
        if it == 1:  # degeneracy: project out directions with tiny curvature (LIO-SAM remapping)
            w, V = np.linalg.eigh(H)
            min_eig = float(w[0])
            V2 = V.copy()
            bad = w < cfg.degeneracy_eigen_threshold
            if bad.any():
                degenerate, n_bad = True, int(bad.sum())
                V2[:, bad] = 0.0
                P = V2 @ V.T
        if degenerate:
            dx = P @ dx
        T = se3.make(se3.exp_so3(dx[:3]) @ T[:3, :3], se3.exp_so3(dx[:3]) @ T[:3, 3] + dx[3:])
        if np.degrees(np.linalg.norm(dx[:3])) < cfg.converge_rot_deg and np.linalg.norm(dx[3:]) * 100 < cfg.converge_trans_cm:
            converged = True
            break
    return MatchResult(T, it, converged, degenerate, min_eig, len(edges), len(surfs), True, n_bad)
