"""Scan-to-map matching (LIO-SAM mapOptimization): point-to-line and point-to-plane
residuals against a local map, Gauss-Newton with degeneracy remapping."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from mrnc_eval.slam import se3
from mrnc_eval.slam.config import MatchingConfig
from mrnc_eval.slam.nearest import KdTree


@dataclass
class LocalMap:
    edges: np.ndarray
    surfs: np.ndarray
    edge_tree: KdTree | None
    surf_tree: KdTree | None

    @classmethod
    def build(cls, edges: np.ndarray, surfs: np.ndarray) -> LocalMap:
        return cls(edges, surfs, KdTree(edges) if len(edges) >= 5 else None, KdTree(surfs) if len(surfs) >= 5 else None)


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
    weakest_direction: tuple[float, ...] = ()  # unit eigenvector of J^T J with the smallest eigenvalue,
    # [rotation (3), translation (3)] in map axes (first iteration); empty when not optimised


@njit(cache=True)
def _plane_rows(q: np.ndarray, o: np.ndarray, nb: np.ndarray, ok: np.ndarray, max_offset: float, J: np.ndarray,
                r: np.ndarray) -> int:
    """Point-to-plane rows (LIO-SAM): plane n.x + 1 = 0 fitted to the 5 neighbours by least
    squares, rejected when a neighbour is > max_offset off; weight s = 1 - 0.9 |pd| / sqrt(|q|).
    Writes J (m, 6) = s [q x n, n] and r = s pd; returns the number of rows. One numba loop
    over the queries with the 3x3 solve written out: longer than 50 lines, but a split would
    pass the plane through arrays in the hottest loop of the replay."""
    m = 0
    for i in range(q.shape[0]):
        if not ok[i]:
            continue
        # normal equations of A x = -1 (5 x 3), a tiny ridge keeps planes through the origin solvable
        a00 = a01 = a02 = a11 = a12 = a22 = 1e-9
        a01 = a02 = a12 = 0.0
        b0 = b1 = b2 = 0.0
        for k in range(5):
            x0, x1, x2 = nb[i, k, 0], nb[i, k, 1], nb[i, k, 2]
            a00 += x0 * x0
            a01 += x0 * x1
            a02 += x0 * x2
            a11 += x1 * x1
            a12 += x1 * x2
            a22 += x2 * x2
            b0 -= x0
            b1 -= x1
            b2 -= x2
        c00 = a11 * a22 - a12 * a12
        c01 = a02 * a12 - a01 * a22
        c02 = a01 * a12 - a02 * a11
        det = a00 * c00 + a01 * c01 + a02 * c02
        if det == 0.0:
            continue
        c11 = a00 * a22 - a02 * a02
        c12 = a01 * a02 - a00 * a12
        c22 = a00 * a11 - a01 * a01
        x = ((c00 * b0 + c01 * b1 + c02 * b2) / det, (c01 * b0 + c11 * b1 + c12 * b2) / det,
             (c02 * b0 + c12 * b1 + c22 * b2) / det)
        nrm = np.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
        if nrm < 1e-9:
            continue
        n0, n1, n2, d = x[0] / nrm, x[1] / nrm, x[2] / nrm, 1.0 / nrm
        planar = True
        for k in range(5):
            if abs(n0 * nb[i, k, 0] + n1 * nb[i, k, 1] + n2 * nb[i, k, 2] + d) > max_offset:
                planar = False
                break
        if not planar:
            continue
        pd = n0 * q[i, 0] + n1 * q[i, 1] + n2 * q[i, 2] + d
        s = 1.0 - 0.9 * abs(pd) / np.sqrt(np.sqrt(q[i, 0] ** 2 + q[i, 1] ** 2 + q[i, 2] ** 2) + 1e-9)
        if s <= 0.1:
            continue
        e0, e1, e2 = q[i, 0] - o[0], q[i, 1] - o[1], q[i, 2] - o[2]  # rotation about the sensor
        J[m, 0] = s * (e1 * n2 - e2 * n1)
        J[m, 1] = s * (e2 * n0 - e0 * n2)
        J[m, 2] = s * (e0 * n1 - e1 * n0)
        J[m, 3], J[m, 4], J[m, 5] = s * n0, s * n1, s * n2
        r[m] = s * pd
        m += 1
    return m


@njit(cache=True)
def _edge_rows(q: np.ndarray, o: np.ndarray, nb: np.ndarray, ok: np.ndarray, J: np.ndarray, r: np.ndarray) -> int:
    """Point-to-line rows (LIO-SAM): the 5 neighbours form a line when the largest eigenvalue of
    their covariance exceeds 3x the second; residual = distance to the line through the centroid,
    weight s = 1 - 0.9 ld."""
    m = 0
    for i in range(q.shape[0]):
        if not ok[i]:
            continue
        c = np.zeros(3)
        for k in range(5):
            for u in range(3):
                c[u] += nb[i, k, u] / 5.0
        cov = np.zeros((3, 3))
        for k in range(5):
            for u in range(3):
                for v in range(3):
                    cov[u, v] += (nb[i, k, u] - c[u]) * (nb[i, k, v] - c[v]) / 5.0
        w, vec = np.linalg.eigh(cov)
        if not w[2] > 3.0 * w[1]:
            continue
        u0, u1, u2 = vec[0, 2], vec[1, 2], vec[2, 2]
        d0, d1, d2 = q[i, 0] - c[0], q[i, 1] - c[1], q[i, 2] - c[2]
        along = d0 * u0 + d1 * u1 + d2 * u2
        p0, p1, p2 = d0 - along * u0, d1 - along * u1, d2 - along * u2
        ld = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
        s = 1.0 - 0.9 * ld
        if s <= 0.1 or ld < 1e-9:
            continue
        n0, n1, n2 = p0 / ld, p1 / ld, p2 / ld
        e0, e1, e2 = q[i, 0] - o[0], q[i, 1] - o[1], q[i, 2] - o[2]  # rotation about the sensor
        J[m, 0] = s * (e1 * n2 - e2 * n1)
        J[m, 1] = s * (e2 * n0 - e0 * n2)
        J[m, 2] = s * (e0 * n1 - e1 * n0)
        J[m, 3], J[m, 4], J[m, 5] = s * n0, s * n1, s * n2
        r[m] = s * ld
        m += 1
    return m


class _Correspondences:
    """Nearest map neighbours of one feature set, re-queried only when the pose has moved more
    than `requery_m` since the last query (0 = every iteration, as LIO-SAM)."""

    def __init__(self, tree: KdTree, cloud: np.ndarray, max_sq: float, requery_m: float) -> None:
        self.tree, self.cloud, self.max_sq, self.requery_m = tree, cloud, max_sq, requery_m
        self.at: np.ndarray | None = None

    def neighbours(self, q: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.at is None or _motion(self.at, T) > self.requery_m:
            d, idx = self.tree.query(q, k=5)
            self.ok, self.nb, self.at = d[:, 4] < self.max_sq ** 0.5, self.cloud[idx], T
        return self.ok, self.nb


def _motion(a: np.ndarray, b: np.ndarray) -> float:
    """Largest displacement (m) of a point 10 m from the sensor between poses a and b."""
    d = se3.inv(a) @ b
    return float(np.linalg.norm(d[:3, 3]) + 10.0 * se3.delta_angle(d))


def _terms(q: np.ndarray, origin: np.ndarray, corr: _Correspondences, T: np.ndarray, kind: str,
           max_offset: float) -> tuple[np.ndarray, np.ndarray]:
    """Residual rows of the transformed features q against the map's planes or lines. A row's
    Jacobian w.r.t. the perturbation T <- [exp(dtheta) R, t + dt] (rotation about the sensor,
    map axes) is [(q - t) x n, n]."""
    ok, nb = corr.neighbours(q, T)
    J, r = np.empty((q.shape[0], 6)), np.empty(q.shape[0])
    m = _plane_rows(q, origin, nb, ok, max_offset, J, r) if kind == "plane" else _edge_rows(q, origin, nb, ok, J, r)
    return J[:m], r[:m]


def match(edges: np.ndarray, surfs: np.ndarray, local_map: LocalMap, guess: np.ndarray,
          cfg: MatchingConfig) -> MatchResult:
    """Refine `guess` (4x4) so the sweep's features lie on the map's lines and planes."""
    use_edges = len(edges) >= cfg.min_edges and local_map.edge_tree is not None
    if (len(surfs) < cfg.min_surfs or local_map.surf_tree is None
            or (not use_edges and not cfg.match_without_edges)):
        return MatchResult(guess, 0, False, False, float("nan"), len(edges), len(surfs), False)
    T = guess.copy()
    P = np.eye(6)
    degenerate, min_eig, converged, it, n_bad = False, float("nan"), False, 0, 0
    weakest: tuple[float, ...] = ()
    edge_corr = (_Correspondences(local_map.edge_tree, local_map.edges, cfg.max_nn_sq_dist_m2, cfg.requery_motion_m)
                 if use_edges and local_map.edge_tree is not None else None)
    surf_corr = _Correspondences(local_map.surf_tree, local_map.surfs, cfg.max_nn_sq_dist_m2, cfg.requery_motion_m)
    for it in range(1, cfg.max_iterations + 1):
        Je, re = np.zeros((0, 6)), np.zeros(0)
        if edge_corr is not None:
            Je, re = _terms(se3.apply(T, edges), T[:3, 3], edge_corr, T, "edge", 0.0)
        Js, rs = _terms(se3.apply(T, surfs), T[:3, 3], surf_corr, T, "plane", cfg.plane_max_offset_m)
        J, r = np.r_[Je, Js], np.r_[re, rs]
        if r.size < cfg.min_correspondences:
            break
        H = J.T @ J
        g = -J.T @ r
        dx = np.linalg.lstsq(H, g, rcond=None)[0]
        if it == 1:  # degeneracy: project out directions with tiny curvature (LIO-SAM remapping)
            w, V = np.linalg.eigh(H)
            min_eig, weakest = float(w[0]), tuple(float(v) for v in V[:, 0])
            V2 = V.copy()
            bad = w < cfg.degeneracy_eigen_threshold
            if bad.any():
                degenerate, n_bad = True, int(bad.sum())
                V2[:, bad] = 0.0
                P = V2 @ V.T
        if degenerate:
            dx = P @ dx
        T = se3.make(se3.exp_so3(dx[:3]) @ T[:3, :3], T[:3, 3] + dx[3:])
        rot_deg, trans_cm = np.degrees(np.linalg.norm(dx[:3])), np.linalg.norm(dx[3:]) * 100
        if rot_deg < cfg.converge_rot_deg and trans_cm < cfg.converge_trans_cm:
            converged = True
            break
    return MatchResult(T, it, converged, degenerate, min_eig, len(edges), len(surfs), True, n_bad, weakest)
