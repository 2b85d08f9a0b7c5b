"""Scan-to-map matching (LIO-SAM mapOptimization): point-to-line and point-to-plane
residuals against a local map, Gauss-Newton with degeneracy remapping."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from mrnc_eval.geometry import rotation, se3
from mrnc_eval.slam import _match_kernels
from mrnc_eval.slam.config import MatchingConfig


@dataclass(kw_only=True)
class LocalMap:
    """The local map a sweep is matched to, with its search trees."""

    edges: np.ndarray
    surfs: np.ndarray
    edge_tree: object | None  # `_match_kernels.build_tree`'s k-d tree of edges; None below 5 points
    surf_tree: object | None

    @classmethod
    def build(cls, edges: np.ndarray, surfs: np.ndarray) -> LocalMap:
        return cls(edges=edges, surfs=surfs, edge_tree=_tree(edges) if len(edges) >= 5 else None,
                   surf_tree=_tree(surfs) if len(surfs) >= 5 else None)


def _tree(points: np.ndarray) -> object:
    return _match_kernels.build_tree(np.ascontiguousarray(points, np.float64))


@dataclass(frozen=True, kw_only=True)
class MatchResult:
    """The outcome of matching one sweep to the local map."""

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

    def __init__(self, tree: object, kind: Correspondence, max_sq: float, max_offset: float,
                 requery_m: float, min_spread: float = 0.0, ground_min_z: float = 0.0) -> None:
        self.tree, self.kind = tree, kind
        self.max_dist, self.max_offset, self.requery_m = max_sq ** 0.5, max_offset, requery_m
        self.min_spread, self.ground_min_z = min_spread, ground_min_z
        self.queried_at: np.ndarray | None = None  # (n, 3) map position of each feature at its last query
        self.fits = np.zeros((0, 6))  # (n, 4) planes [n, d] or (n, 6) lines [centroid, direction]; NaN: none
        self.moved = np.zeros(0, np.int64)  # the re-query test's buffer: indices of the features that moved

    def rows(self, features: np.ndarray, T: np.ndarray, pivot: np.ndarray | None, J: np.ndarray,
             r: np.ndarray) -> int:
        """Residual rows of the features (sensor frame) at pose T, written into J[:m] (Jacobian
        w.r.t. the perturbation T <- [exp(dtheta) R, t + dt]: rotation about the sensor, map axes;
        about the point `pivot` of the sensor frame when given) and r[:m]; returns m. Planes whose
        normal is within acos(ground_min_z) of the map's z axis (ground; 0 = off) keep only their
        z, roll and pitch columns (LeGO-LOAM's split: the ground fixes z, roll and pitch, the rest
        of the scene x, y and yaw): the small tilts of rough-ground normals otherwise pose as x, y
        and yaw information that the degeneracy test trusts (eigenvalues of J^T J in the hundreds
        on bare ground), and the yaw walks by degrees per sweep."""
        q = se3.apply(T, features)
        if self.queried_at is None:
            self.fits = np.empty((len(q), 4 if self.kind is Correspondence.PLANE else 6))
            self.moved = np.empty(len(q), np.int64)
            self._fit(q, None)
            self.queried_at = q
        else:
            moved = self.moved[:_match_kernels.moved(q, self.queried_at, self.requery_m, self.moved)]
            if moved.size:
                q_moved = q[moved]
                self._fit(q_moved, moved)
                self.queried_at[moved] = q_moved
        origin = np.ascontiguousarray(T[:3, 3] if pivot is None else T[:3, :3] @ pivot + T[:3, 3], np.float64)
        if self.kind is Correspondence.PLANE:
            return _match_kernels.plane_rows(q, origin, self.fits, self.ground_min_z, J, r)
        return _match_kernels.edge_rows(q, origin, self.fits, J, r)

    def _fit(self, q: np.ndarray, rows: np.ndarray | None) -> None:
        """Search the 5 nearest map points of the map points q and fit their planes or lines into
        self.fits[rows] (rows None: all), in one C pass; a feature whose 5th neighbour is not
        within max_dist gets none (NaN)."""
        if self.kind is Correspondence.PLANE:
            _match_kernels.fit_planes(self.tree, q, self.max_dist, self.max_offset, self.min_spread, self.fits, rows)
        else:
            _match_kernels.fit_lines(self.tree, q, self.max_dist, self.fits, rows)


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
    edge_corr = (_Correspondences(local_map.edge_tree, Correspondence.LINE, cfg.max_nn_sq_dist_m2, 0.0,
                                  cfg.requery_motion_m) if use_edges and local_map.edge_tree is not None else None)
    surf_corr = _Correspondences(local_map.surf_tree, Correspondence.PLANE, cfg.max_nn_sq_dist_m2,
                                 cfg.plane_max_offset_m, cfg.requery_motion_m, cfg.plane_min_spread_m,
                                 cfg.ground_normal_min_z)
    T, deg, converged, it = guess.copy(), _Degeneracy(), False, 0
    rows = np.empty((len(edges) + len(surfs), 6)), np.empty(len(edges) + len(surfs))  # every iteration's J, r
    for it in range(1, cfg.max_iterations + 1):
        J, r = _stacked_rows(edge_corr, surf_corr, edges, surfs, T, pivot, rows)
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
                  rows: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The edge rows, then the plane rows: J (m, 6) and r (m,), the leading rows of the buffers `rows`
    (n_edges + n_surfs rows; one allocation per match, not two per iteration and a concatenation)."""
    J, r = rows
    m = edge_corr.rows(edges, T, pivot, J, r) if edge_corr is not None else 0
    m += surf_corr.rows(surfs, T, pivot, J[m:], r[m:])
    return J[:m], r[:m]


_UP = np.array([0.0, 0.0, 1.0])
_HEADING_AND_XY = np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0, 0.0, 0.0],
                            [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]])  # yaw, x, y ([rot, trans], map axes)


def tilt_correction_deg(res: MatchResult, guess: np.ndarray) -> float:
    """The angle (deg) between the gravity direction of the guess and of the match: the part of
    the match's correction that roll and pitch make, whatever its yaw."""
    cos = float(np.clip((guess[:3, :3].T @ _UP) @ (res.pose[:3, :3].T @ _UP), -1.0, 1.0))
    return float(np.degrees(np.arccos(cos)))


def keep_tilt(res: MatchResult, guess: np.ndarray) -> MatchResult:
    """The match's roll, pitch and z on the guess's yaw, x and y: the guess turned by the smallest
    map-frame rotation (about a horizontal axis, so no yaw) that gives it the match's gravity
    direction. Yaw, x and y join the degenerate directions (the IMU carries them)."""
    up_m = guess[:3, :3] @ (res.pose[:3, :3].T @ _UP)  # the matched up, seen through the guess (map axes)
    axis = np.cross(up_m, _UP)
    s, c = float(np.linalg.norm(axis)), float(up_m @ _UP)
    turn = rotation.exp(axis / s * np.arctan2(s, c)) if s > 1e-12 else np.eye(3)
    pose = se3.make(turn @ guess[:3, :3], np.r_[guess[:2, 3], res.pose[2, 3]])
    free = _HEADING_AND_XY if res.degenerate_directions is None or not len(res.degenerate_directions) \
        else np.vstack([res.degenerate_directions, _HEADING_AND_XY])
    _, sv, vt = np.linalg.svd(free, full_matrices=False)
    directions = vt[sv > 1e-6 * sv[0]]
    return replace(res, pose=pose, degenerate=True, n_degenerate=len(directions), degenerate_directions=directions)
