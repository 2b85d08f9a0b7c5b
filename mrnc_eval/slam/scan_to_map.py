"""Scan-to-map matching (LIO-SAM mapOptimization): point-to-line and point-to-plane
residuals against a local map, Gauss-Newton with degeneracy remapping."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from numba import njit

from mrnc_eval.geometry import rotation, se3
from mrnc_eval.slam.config import MatchingConfig
from mrnc_eval.slam.nearest import KdTree


@dataclass(kw_only=True)
class LocalMap:
    edges: np.ndarray
    surfs: np.ndarray
    edge_tree: KdTree | None
    surf_tree: KdTree | None

    @classmethod
    def build(cls, edges: np.ndarray, surfs: np.ndarray) -> LocalMap:
        return cls(edges=edges, surfs=surfs, edge_tree=KdTree(edges) if len(edges) >= 5 else None,
                   surf_tree=KdTree(surfs) if len(surfs) >= 5 else None)


@dataclass(frozen=True, kw_only=True)
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
    eigenvalues: tuple[float, ...] = ()  # of J^T J at the first iteration, ascending; empty when not optimised
    degenerate_directions: np.ndarray | None = None  # (k, 6) unit eigenvectors projected out, [rot, trans] in
    # map axes (rotation about the sensor); None when not optimised: then every direction is the guess's


@njit(cache=True, nogil=True)
def _fit_planes(cloud: np.ndarray, idx: np.ndarray, ok: np.ndarray, max_offset: float, min_spread: float,
                planes: np.ndarray) -> None:
    """Plane n.x + d = 0 (|n| = 1) through the 5 neighbours cloud[idx[i]] of each query (LIO-SAM:
    least squares A x = -1, rejected when a neighbour is > max_offset off; not in LIO-SAM: also
    rejected when the neighbours spread less than min_spread (std, m) across their line, since
    nearly collinear neighbours, one ring arc of far ground, leave the normal free to turn about
    that line, and a wrong normal 30 m away poses as yaw information). planes (n, 4) =
    [n, d]; a row of NaN where no plane. Depends on the neighbours only, so it is fitted once
    per nearest-neighbour query, not per iteration."""
    for i in range(idx.shape[0]):
        planes[i, 0] = np.nan
        if not ok[i]:
            continue
        # normal equations of A x = -1 (5 x 3), a tiny ridge keeps planes through the origin solvable
        a00 = a11 = a22 = 1e-9
        a01 = a02 = a12 = 0.0
        b0 = b1 = b2 = 0.0
        for k in range(5):
            j = idx[i, k]
            x0, x1, x2 = cloud[j, 0], cloud[j, 1], cloud[j, 2]
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
        x0 = (c00 * b0 + c01 * b1 + c02 * b2) / det
        x1 = (c01 * b0 + c11 * b1 + c12 * b2) / det
        x2 = (c02 * b0 + c12 * b1 + c22 * b2) / det
        nrm = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        if nrm < 1e-9:
            continue
        n0, n1, n2, d = x0 / nrm, x1 / nrm, x2 / nrm, 1.0 / nrm
        planar = True
        for k in range(5):
            j = idx[i, k]
            if abs(n0 * cloud[j, 0] + n1 * cloud[j, 1] + n2 * cloud[j, 2] + d) > max_offset:
                planar = False
                break
        if planar and _in_plane_spread(cloud, idx[i], n0, n1, n2) >= min_spread * min_spread:
            planes[i, 0], planes[i, 1], planes[i, 2], planes[i, 3] = n0, n1, n2, d


@njit(cache=True, nogil=True)
def _in_plane_spread(cloud: np.ndarray, idx: np.ndarray, n0: float, n1: float, n2: float) -> float:
    """Smaller eigenvalue (m^2) of the 2x2 covariance of the points cloud[idx] projected on the
    plane with normal n."""
    u0, u1, u2 = (n1, -n0, 0.0) if abs(n2) < 0.9 else (0.0, n2, -n1)  # a vector normal to n
    un = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    u0, u1, u2 = u0 / un, u1 / un, u2 / un
    v0, v1, v2 = n1 * u2 - n2 * u1, n2 * u0 - n0 * u2, n0 * u1 - n1 * u0
    c0 = c1 = c2 = 0.0
    for k in range(idx.size):
        c0 += cloud[idx[k], 0] / idx.size
        c1 += cloud[idx[k], 1] / idx.size
        c2 += cloud[idx[k], 2] / idx.size
    a = b = d = 0.0
    for k in range(idx.size):
        x0, x1, x2 = cloud[idx[k], 0] - c0, cloud[idx[k], 1] - c1, cloud[idx[k], 2] - c2
        pu, pv = x0 * u0 + x1 * u1 + x2 * u2, x0 * v0 + x1 * v1 + x2 * v2
        a += pu * pu / idx.size
        b += pu * pv / idx.size
        d += pv * pv / idx.size
    return float(0.5 * (a + d) - np.sqrt(0.25 * (a - d) ** 2 + b * b))


@njit(cache=True, nogil=True)
def _fit_lines(cloud: np.ndarray, idx: np.ndarray, ok: np.ndarray, lines: np.ndarray) -> None:
    """Line through the 5 neighbours of each query (LIO-SAM): their centroid and the principal
    axis of their covariance, kept when its eigenvalue exceeds 3x the second. lines (n, 6) =
    [centroid, unit direction]; a row of NaN where no line. The 3x3 eigenproblem is solved in
    closed form (trigonometric roots, eigenvector from a cross product of two rows of
    cov - l1 I): a LAPACK call per point cost more than the rest of the matching."""
    for i in range(idx.shape[0]):
        lines[i, 0] = np.nan
        if not ok[i]:
            continue
        c0 = c1 = c2 = 0.0
        for k in range(5):
            j = idx[i, k]
            c0 += cloud[j, 0] / 5.0
            c1 += cloud[j, 1] / 5.0
            c2 += cloud[j, 2] / 5.0
        a00 = a01 = a02 = a11 = a12 = a22 = 0.0
        for k in range(5):
            j = idx[i, k]
            d0, d1, d2 = cloud[j, 0] - c0, cloud[j, 1] - c1, cloud[j, 2] - c2
            a00 += d0 * d0 / 5.0
            a01 += d0 * d1 / 5.0
            a02 += d0 * d2 / 5.0
            a11 += d1 * d1 / 5.0
            a12 += d1 * d2 / 5.0
            a22 += d2 * d2 / 5.0
        u = _principal_axis(a00, a01, a02, a11, a12, a22)
        if u[0] == u[0]:  # not NaN: a line
            lines[i, 0], lines[i, 1], lines[i, 2] = c0, c1, c2
            lines[i, 3], lines[i, 4], lines[i, 5] = u[0], u[1], u[2]


@njit(cache=True, nogil=True)
def _principal_axis(a00: float, a01: float, a02: float, a11: float, a12: float,
                    a22: float) -> tuple[float, float, float]:
    """Unit eigenvector of the largest eigenvalue l1 of the symmetric 3x3 [[a00 a01 a02] [. a11 a12]
    [. . a22]] when l1 > 3 l2 (a line), else (NaN, NaN, NaN)."""
    none = (np.nan, np.nan, np.nan)
    q = (a00 + a11 + a22) / 3.0
    off = a01 * a01 + a02 * a02 + a12 * a12
    p2 = (a00 - q) ** 2 + (a11 - q) ** 2 + (a22 - q) ** 2 + 2.0 * off
    if p2 <= 0.0:
        return none  # isotropic (or all points equal)
    p = np.sqrt(p2 / 6.0)
    b00, b11, b22 = (a00 - q) / p, (a11 - q) / p, (a22 - q) / p
    b01, b02, b12 = a01 / p, a02 / p, a12 / p
    half_det = 0.5 * (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02) + b02 * (b01 * b12 - b11 * b02))
    phi = np.arccos(min(1.0, max(-1.0, half_det))) / 3.0
    l1 = q + 2.0 * p * np.cos(phi)
    l3 = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    l2 = 3.0 * q - l1 - l3
    if not l1 > 3.0 * l2:
        return none
    r0 = (a00 - l1, a01, a02)  # rows of cov - l1 I: the eigenvector is orthogonal to all three
    r1 = (a01, a11 - l1, a12)
    r2 = (a02, a12, a22 - l1)
    best, v0, v1, v2 = -1.0, 0.0, 0.0, 0.0
    for x, y in ((r0, r1), (r0, r2), (r1, r2)):
        w0, w1, w2 = x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]
        n = w0 * w0 + w1 * w1 + w2 * w2
        if n > best:
            best, v0, v1, v2 = n, w0, w1, w2
    if best <= 0.0:
        return none
    s = 1.0 / np.sqrt(best)
    return (v0 * s, v1 * s, v2 * s)


@njit(cache=True, nogil=True)
def _write_row(J: np.ndarray, r: np.ndarray, m: int, q: np.ndarray, o: np.ndarray, n0: float, n1: float, n2: float,
               s: float, residual: float) -> None:
    """Row m of a point q with unit direction n and weight s: J = s [(q - o) x n, n] (rotation
    about the point o, map axes; then translation) and r = s residual."""
    e0, e1, e2 = q[0] - o[0], q[1] - o[1], q[2] - o[2]
    J[m, 0] = s * (e1 * n2 - e2 * n1)
    J[m, 1] = s * (e2 * n0 - e0 * n2)
    J[m, 2] = s * (e0 * n1 - e1 * n0)
    J[m, 3], J[m, 4], J[m, 5] = s * n0, s * n1, s * n2
    r[m] = s * residual


@njit(cache=True, nogil=True)
def _plane_rows(q: np.ndarray, o: np.ndarray, planes: np.ndarray, J: np.ndarray, r: np.ndarray) -> int:
    """Point-to-plane rows (LIO-SAM): pd = n.q + d, weight s = 1 - 0.9 |pd| / sqrt(|q|), kept when
    s > 0.1, direction n. Writes J (m, 6) and r (`_write_row`); returns m."""
    m = 0
    for i in range(q.shape[0]):
        n0, n1, n2, d = planes[i, 0], planes[i, 1], planes[i, 2], planes[i, 3]
        if n0 != n0:  # NaN: no plane
            continue
        pd = n0 * q[i, 0] + n1 * q[i, 1] + n2 * q[i, 2] + d
        s = 1.0 - 0.9 * abs(pd) / np.sqrt(np.sqrt(q[i, 0] ** 2 + q[i, 1] ** 2 + q[i, 2] ** 2) + 1e-9)
        if s <= 0.1:
            continue
        _write_row(J, r, m, q[i], o, n0, n1, n2, s, pd)
        m += 1
    return m


@njit(cache=True, nogil=True)
def _edge_rows(q: np.ndarray, o: np.ndarray, lines: np.ndarray, J: np.ndarray, r: np.ndarray) -> int:
    """Point-to-line rows (LIO-SAM): ld = distance to the line, weight s = 1 - 0.9 ld, kept when
    s > 0.1; the row's direction is the unit normal from the line to the point (`_write_row`)."""
    m = 0
    for i in range(q.shape[0]):
        if lines[i, 0] != lines[i, 0]:  # NaN: no line
            continue
        u0, u1, u2 = lines[i, 3], lines[i, 4], lines[i, 5]
        d0, d1, d2 = q[i, 0] - lines[i, 0], q[i, 1] - lines[i, 1], q[i, 2] - lines[i, 2]
        along = d0 * u0 + d1 * u1 + d2 * u2
        p0, p1, p2 = d0 - along * u0, d1 - along * u1, d2 - along * u2
        ld = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
        s = 1.0 - 0.9 * ld
        if s <= 0.1 or ld < 1e-9:
            continue
        _write_row(J, r, m, q[i], o, p0 / ld, p1 / ld, p2 / ld, s, ld)
        m += 1
    return m


class Correspondence(Enum):
    """What a feature is matched to in the local map."""

    LINE = "line"  # an edge feature: point-to-line (5 neighbours along a line)
    PLANE = "plane"  # a surface feature: point-to-plane (5 neighbours on a plane)


class _Correspondences:
    """The map's plane or line at each feature, from its 5 nearest map points. A feature's
    neighbours are re-queried and its fit redone only once it has moved more than `requery_m`
    since its last query (0 = every iteration, as LIO-SAM): the first Gauss-Newton step moves the
    near features by millimetres and the far ones by centimetres, and with the map's 0.2-0.4 m
    voxels the neighbours of a feature that moved a few centimetres fit the same line or plane.
    Neighbours farther than sqrt(max_sq) are not searched for: a feature whose 5th neighbour is
    that far has no correspondence anyway."""

    def __init__(self, tree: KdTree, cloud: np.ndarray, kind: Correspondence, max_sq: float, max_offset: float,
                 requery_m: float, min_spread: float = 0.0) -> None:
        self.tree, self.cloud, self.kind = tree, cloud, kind
        self.max_dist, self.max_offset, self.requery_m = max_sq ** 0.5, max_offset, requery_m
        self.min_spread = min_spread
        self.queried_at: np.ndarray | None = None  # (n, 3) map position of each feature at its last query
        self.fits = np.zeros((0, 6))

    def rows(self, features: np.ndarray, T: np.ndarray,
             pivot: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Residual rows of the features (sensor frame) at pose T: Jacobian (m, 6) w.r.t. the
        perturbation T <- [exp(dtheta) R, t + dt] (rotation about the sensor, map axes; about the
        point `pivot` of the sensor frame when given) and residual (m,)."""
        q = se3.apply(T, features)
        if self.queried_at is None:
            self.fits, self.queried_at = self._fit(q), q
        else:
            moved = _moved(q, self.queried_at, self.requery_m)
            if moved.size:
                self.fits[moved] = self._fit(q[moved])
                self.queried_at[moved] = q[moved]
        J, r = np.empty((len(q), 6)), np.empty(len(q))
        origin = np.ascontiguousarray(T[:3, 3] if pivot is None else T[:3, :3] @ pivot + T[:3, 3])
        m = (_plane_rows(q, origin, self.fits, J, r) if self.kind is Correspondence.PLANE
             else _edge_rows(q, origin, self.fits, J, r))
        return J[:m], r[:m]

    def _fit(self, q: np.ndarray) -> np.ndarray:
        """The plane (n, 4) or line (n, 6) rows of the map points q (`_fit_planes`, `_fit_lines`)."""
        d, idx = self.tree.query(q, k=5, max_dist=self.max_dist)
        ok = d[:, 4] < self.max_dist
        idx[~ok] = 0  # unmatched rows point past the cloud's end
        if self.kind is Correspondence.PLANE:
            fits = np.empty((len(q), 4))
            _fit_planes(self.cloud, idx, ok, self.max_offset, self.min_spread, fits)
        else:
            fits = np.empty((len(q), 6))
            _fit_lines(self.cloud, idx, ok, fits)
        return fits


@njit(cache=True, nogil=True)
def _moved(q: np.ndarray, queried_at: np.ndarray, requery_m: float) -> np.ndarray:
    """Indices of the rows of q (n, 3) farther than requery_m (m) from the same row of queried_at."""
    out = np.empty(q.shape[0], np.int64)
    n = 0
    lim = requery_m * requery_m
    for i in range(q.shape[0]):
        d0, d1, d2 = q[i, 0] - queried_at[i, 0], q[i, 1] - queried_at[i, 1], q[i, 2] - queried_at[i, 2]
        if d0 * d0 + d1 * d1 + d2 * d2 > lim:
            out[n] = i
            n += 1
    return out[:n]


def _tangent_from(guess: np.ndarray, T: np.ndarray) -> np.ndarray:
    """T - guess as [rotation vector of R_T R_guess^T, t_T - t_guess] (map axes, the update's tangent)."""
    rot = rotation.log(T[:3, :3] @ guess[:3, :3].T)
    return np.asarray(np.r_[rot, T[:3, 3] - guess[:3, 3]], np.float64)


def _update(T: np.ndarray, dx: np.ndarray, pivot: np.ndarray | None) -> np.ndarray:
    """T after the step dx = [dtheta, dt] (map axes): rotation about the sensor, or about `pivot`."""
    turn = se3.exp_so3(dx[:3])
    if pivot is None:
        return se3.make(turn @ T[:3, :3], T[:3, 3] + dx[3:])
    c = T[:3, :3] @ pivot + T[:3, 3]
    return se3.make(turn @ T[:3, :3], turn @ (T[:3, 3] - c) + c + dx[3:])


def _about_sensor(directions: np.ndarray, pivot_offset: np.ndarray) -> np.ndarray:
    """Unit directions [dtheta, dt] about a pivot at sensor + pivot_offset (map axes) as directions
    about the sensor: the sensor moves by dt + dtheta x (sensor - pivot)."""
    moved = np.c_[directions[:, :3], directions[:, 3:] + np.cross(directions[:, :3], -pivot_offset)]
    return np.asarray(moved / np.linalg.norm(moved, axis=1, keepdims=True), np.float64)


def _ground_rows_vertical_only(J: np.ndarray, min_normal_z: float) -> None:
    """Plane rows whose normal is within acos(min_normal_z) of the map's z axis (ground) keep only
    their z, roll and pitch columns, in place (LeGO-LOAM's split: the ground fixes z, roll and
    pitch, the rest of the scene x, y and yaw). The small tilts of rough-ground normals otherwise
    pose as x, y and yaw information that the degeneracy test trusts (eigenvalues of J^T J in the
    hundreds on bare ground), and the yaw walks by degrees per sweep."""
    _zero_ground_xy_yaw(J, min_normal_z)


@njit(cache=True, nogil=True)
def _zero_ground_xy_yaw(J: np.ndarray, min_normal_z: float) -> None:
    """`_ground_rows_vertical_only` in one pass (numpy's masks and np.ix_ copies were ~4 % of a sweep):
    |n_z| > min_normal_z |n| with n = J[m, 3:] (s * normal), the norm summed in numpy's order."""
    for m in range(J.shape[0]):
        n0, n1, n2 = J[m, 3], J[m, 4], J[m, 5]
        if abs(n2) > min_normal_z * np.sqrt(n0 * n0 + n1 * n1 + n2 * n2):
            J[m, 2] = 0.0
            J[m, 3] = 0.0
            J[m, 4] = 0.0


def match(edges: np.ndarray, surfs: np.ndarray, local_map: LocalMap, guess: np.ndarray,
          cfg: MatchingConfig, prior: np.ndarray | None = None, pivot: np.ndarray | None = None) -> MatchResult:
    """Refine `guess` (4x4) so the sweep's features lie on the map's lines and planes. `prior` (6,),
    [rot, trans] in map axes, in J^T J's units (m^2 per rad^2 for rotations: a residual row of 1 m per
    unit of the direction): information holding the pose towards the guess, added to J^T J, so a
    direction the sweep measures weakly (a few far poles' yaw) moves only part of the way; the
    degeneracy test still looks at the sweep's own J^T J. `pivot` (3,), a point of the sensor frame
    (the base origin): rotations turn about it, so the translation held along degenerate directions
    is the pivot's; about the sensor (LIO-SAM), a roll or pitch the ground corrects would drag a
    base that the wheels placed by h x the angle (1.9 m mast: 3 cm per degree) each sweep."""
    use_edges = len(edges) >= cfg.min_edges and local_map.edge_tree is not None
    if (len(surfs) < cfg.min_surfs or local_map.surf_tree is None
            or (not use_edges and not cfg.match_without_edges)):
        return MatchResult(pose=guess, iterations=0, converged=False, degenerate=False, min_eigenvalue=float("nan"),
                           n_edges=len(edges), n_surfs=len(surfs), optimised=False)
    edge_corr = (_Correspondences(local_map.edge_tree, local_map.edges, Correspondence.LINE, cfg.max_nn_sq_dist_m2,
                                  0.0, cfg.requery_motion_m) if use_edges and local_map.edge_tree is not None else None)
    surf_corr = _Correspondences(local_map.surf_tree, local_map.surfs, Correspondence.PLANE, cfg.max_nn_sq_dist_m2,
                                 cfg.plane_max_offset_m, cfg.requery_motion_m, cfg.plane_min_spread_m)
    T, deg, converged, it = guess.copy(), _Degeneracy(), False, 0
    for it in range(1, cfg.max_iterations + 1):
        J, r = _stacked_rows(edge_corr, surf_corr, edges, surfs, T, pivot, cfg.ground_normal_min_z)
        if r.size < cfg.min_correspondences:
            break
        H, g = J.T @ J, -J.T @ r
        if it == 1:  # degeneracy: project out directions with tiny curvature (LIO-SAM remapping)
            deg = _degenerate_directions(H, cfg.degeneracy_eigen_threshold)
        dx = _step(H, g, deg, prior, guess, T)
        T = _update(T, dx, pivot)
        if _small(dx, cfg):
            converged = True
            break
    directions = deg.directions
    if pivot is not None and len(directions):  # report them about the sensor, as without a pivot
        directions = _about_sensor(directions, T[:3, :3] @ pivot)
    return MatchResult(pose=T, iterations=it, converged=converged, degenerate=deg.degenerate,
                       min_eigenvalue=deg.min_eigenvalue, n_edges=len(edges), n_surfs=len(surfs), optimised=True,
                       n_degenerate=len(deg.directions), weakest_direction=deg.weakest, eigenvalues=deg.eigenvalues,
                       degenerate_directions=directions)


@dataclass(frozen=True, kw_only=True)
class _Degeneracy:
    """The first iteration's eigen-analysis of J^T J; the defaults: none yet (every direction measured)."""

    eigenvalues: tuple[float, ...] = ()  # ascending
    weakest: tuple[float, ...] = ()  # unit eigenvector of the smallest eigenvalue, [rot, trans] in map axes
    measured: np.ndarray = field(default_factory=lambda: np.eye(6))  # (6, k) eigenvectors kept, as columns
    projection: np.ndarray = field(default_factory=lambda: np.eye(6))  # P = V' V^T, the degenerate ones zeroed
    directions: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))  # (k, 6) eigenvectors projected out

    @property
    def degenerate(self) -> bool:
        return len(self.directions) > 0

    @property
    def min_eigenvalue(self) -> float:
        return self.eigenvalues[0] if self.eigenvalues else float("nan")


def _degenerate_directions(H: np.ndarray, threshold: float) -> _Degeneracy:
    """LIO-SAM's degeneracy remapping: the eigenvectors of J^T J whose eigenvalue is below
    `threshold` are directions the sweep does not measure; updates along them are projected out."""
    w, V = np.linalg.eigh(H)
    bad = w < threshold
    projection = np.eye(6)
    if bad.any():
        V2 = V.copy()
        V2[:, bad] = 0.0
        projection = V2 @ V.T
    return _Degeneracy(eigenvalues=tuple(float(v) for v in w), weakest=tuple(float(v) for v in V[:, 0]),
                       measured=V[:, ~bad], projection=projection, directions=V[:, bad].T.copy())


def _step(H: np.ndarray, g: np.ndarray, deg: _Degeneracy, prior: np.ndarray | None, guess: np.ndarray,
          T: np.ndarray) -> np.ndarray:
    """The Gauss-Newton update dx = [dtheta, dt] (map axes) of H dx = g, without the degenerate
    directions; with a prior, solved within the measured directions with the prior's information
    pulling towards the guess (projecting a prior-held solution afterwards would turn its
    translation into yaw: H's eigenvectors mix the two)."""
    if prior is None:
        dx: np.ndarray = np.linalg.lstsq(H, g, rcond=None)[0]
        return deg.projection @ dx if deg.degenerate else dx
    g_held = g - prior * _tangent_from(guess, T)
    good = deg.measured
    return np.asarray(good @ np.linalg.lstsq(good.T @ (H + np.diag(prior)) @ good, good.T @ g_held, rcond=None)[0])


def _small(dx: np.ndarray, cfg: MatchingConfig) -> bool:
    """Converged: the step turns less than converge_rot_deg and moves less than converge_trans_cm."""
    return bool(np.degrees(np.linalg.norm(dx[:3])) < cfg.converge_rot_deg
                and np.linalg.norm(dx[3:]) * 100 < cfg.converge_trans_cm)


def _stacked_rows(edge_corr: _Correspondences | None, surf_corr: _Correspondences, edges: np.ndarray,
                  surfs: np.ndarray, T: np.ndarray, pivot: np.ndarray | None,
                  ground_normal_min_z: float) -> tuple[np.ndarray, np.ndarray]:
    """The edge rows, then the plane rows (ground planes vertical-only when ground_normal_min_z > 0)."""
    Je, re = edge_corr.rows(edges, T, pivot) if edge_corr is not None else (np.zeros((0, 6)), np.zeros(0))
    Js, rs = surf_corr.rows(surfs, T, pivot)
    if ground_normal_min_z > 0:
        _ground_rows_vertical_only(Js, ground_normal_min_z)
    return np.r_[Je, Js], np.r_[re, rs]
