"""Vectorised SO(3)/SE(3) helpers on stacks of poses (N, 4, 4). Pure numpy."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.data import F64, Trajectory

EPS = np.finfo(float).eps


def quat_xyzw_to_matrix(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N, 4) xyzw -> (N, 3, 3). Quaternions are normalised (scaled by sqrt(2/|q|^2)) as
    evo does; |q|^2 < 4 eps gives the identity."""
    q = np.asarray(q, dtype=float).reshape(-1, 4)
    n2 = np.einsum("ij,ij->i", q, q)
    ok = n2 >= 4.0 * EPS
    s = np.sqrt(2.0 / np.where(ok, n2, 1.0))
    s[~ok] = 0.0
    # contiguous component columns and one (9, N) block: ~3x faster than strided writes
    x, y, z, w = (np.ascontiguousarray(q[:, k]) * s for k in range(4))
    m = np.empty((9, q.shape[0]))
    m[0] = 1.0 - y * y - z * z
    m[1] = x * y - z * w
    m[2] = x * z + y * w
    m[3] = x * y + z * w
    m[4] = 1.0 - x * x - z * z
    m[5] = y * z - x * w
    m[6] = x * z - y * w
    m[7] = y * z + x * w
    m[8] = 1.0 - x * x - y * y
    r = np.ascontiguousarray(m.T).reshape(-1, 3, 3)
    r[~ok] = np.eye(3)
    return r


def matrix_to_quat_xyzw(r: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N, 3, 3) -> (N, 4) unit xyzw quaternions (Shepperd's method: each from the largest of
    w^2, x^2, y^2, z^2, so well conditioned everywhere; the sign is not canonicalised)."""
    r = np.asarray(r, dtype=float).reshape(-1, 3, 3)
    diag = np.stack([r[:, 0, 0], r[:, 1, 1], r[:, 2, 2]], axis=1)
    trace = diag.sum(axis=1)
    choice = np.argmax(np.column_stack([diag, trace]), axis=1)
    q = np.empty((r.shape[0], 4))
    t = choice == 3
    q[t, 0] = r[t, 2, 1] - r[t, 1, 2]
    q[t, 1] = r[t, 0, 2] - r[t, 2, 0]
    q[t, 2] = r[t, 1, 0] - r[t, 0, 1]
    q[t, 3] = 1.0 + trace[t]
    for i in range(3):  # three cases, each vectorised over the rotations it covers
        j, k = (i + 1) % 3, (i + 2) % 3
        c = choice == i
        q[c, i] = 1.0 - trace[c] + 2.0 * r[c, i, i]
        q[c, j] = r[c, j, i] + r[c, i, j]
        q[c, k] = r[c, k, i] + r[c, i, k]
        q[c, 3] = r[c, k, j] - r[c, j, k]
    unit: NDArray[np.float64] = q / np.linalg.norm(q, axis=1)[:, None]
    return unit


def quat_multiply(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Hamilton products a b of (N, 4) or (4,) xyzw quaternions (the rotation R_a R_b)."""
    ax, ay, az, aw = (a[..., k] for k in range(4))
    bx, by, bz, bw = (b[..., k] for k in range(4))
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def quat_relative_angle(q_a: NDArray[np.float64], q_b: NDArray[np.float64]) -> NDArray[np.float64]:
    """|angle| (rad) of R_a^T R_b from (N, 4) xyzw quaternions of any length: the matrix
    route's number (evo's, to rounding ~eps/angle) at a fraction of its time and memory."""
    q = quat_multiply(q_a * np.array([-1.0, -1.0, -1.0, 1.0]), q_b)  # conj(a) b: |q| = |a| |b|
    angle: NDArray[np.float64] = 2.0 * np.arctan2(np.linalg.norm(q[:, :3], axis=1), np.abs(q[:, 3]))
    return angle


def rotations(traj: Trajectory) -> NDArray[np.float64]:
    """(N, 3, 3) rotation matrices of a trajectory: as read when the file stored matrices
    (KITTI; possibly not quite orthonormal, used unchanged as evo does), else from the
    quaternions (normalised)."""
    if traj.rotations is not None:
        return traj.rotations
    return quat_xyzw_to_matrix(traj.quat_xyzw)


def nearest_orthonormal(r: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each matrix whose R R^T differs from I by more than scipy's tolerance (1e-12 absolute
    off the diagonal, 1e-5 relative on it) replaced by its polar factor U V^T, the nearest
    rotation; orthonormal ones pass unchanged. This is what scipy's Rotation.from_matrix
    (and so evo's angle) does with matrices printed to limited precision."""
    rows = [np.ascontiguousarray(r[:, i, :]) for i in range(3)]
    off = np.zeros(r.shape[0], dtype=bool)
    for i in range(3):  # the six distinct entries of R R^T, row by row (a batched matmul is ~20x slower)
        for j in range(i, 3):
            g = np.einsum("ij,ij->i", rows[i], rows[j])
            off |= np.abs(g - 1.0) > 1e-12 + 1e-5 if i == j else np.abs(g) > 1e-12
    if not off.any():
        return r
    out = r.copy()
    u, _, vt = np.linalg.svd(r[off])
    out[off] = np.matmul(u, vt)
    return out


def transpose(r: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.swapaxes(r, -1, -2)


def relative(r_i: F64, p_i: F64, r_j: F64, p_j: F64) -> tuple[F64, F64]:
    """Rotation and translation of T_i^-1 T_j for stacks: (R_i^T R_j, R_i^T (p_j - p_i))."""
    rt = transpose(r_i)
    return np.matmul(rt, r_j), np.einsum("nij,nj->ni", rt, p_j - p_i)


def homogeneous(r: NDArray[np.float64], t: NDArray[np.float64]) -> NDArray[np.float64]:
    """(..., 3, 3) rotations and (..., 3) translations -> (..., 4, 4) poses [R t; 0 1]: the one
    place a pose matrix is assembled (the SLAM's se3.make uses it too)."""
    r = np.asarray(r, dtype=float)
    out = np.zeros((*r.shape[:-2], 4, 4))
    out[..., :3, :3] = r
    out[..., :3, 3] = t
    out[..., 3, 3] = 1.0
    return out


def poses(traj: Trajectory) -> NDArray[np.float64]:
    """(N, 4, 4) homogeneous poses of a trajectory."""
    return homogeneous(rotations(traj), traj.positions)


def inverse(t: NDArray[np.float64]) -> NDArray[np.float64]:
    """Batched SE(3) inverse [R^T, -R^T t]."""
    out = np.zeros_like(t)
    rt = np.swapaxes(t[..., :3, :3], -1, -2)
    out[..., :3, :3] = rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", rt, t[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def compose(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Batched product a @ b of (N, 4, 4) stacks."""
    out: NDArray[np.float64] = np.matmul(a, b)
    return out


def rotation_angle(r: NDArray[np.float64]) -> NDArray[np.float64]:
    """|angle| (rad) of each rotation, through the quaternion: 2 atan2(|q_xyz|, |q_w|).

    More accurate than arccos((tr R - 1) / 2) for small angles (error ~eps/theta there).
    A matrix that is not orthonormal is first replaced by the nearest rotation, as evo does.
    """
    q = matrix_to_quat_xyzw(nearest_orthonormal(np.asarray(r, dtype=float).reshape(-1, 3, 3)))
    angle: NDArray[np.float64] = 2.0 * np.arctan2(np.linalg.norm(q[:, :3], axis=1), np.abs(q[:, 3]))
    return angle


def yaw_pitch_roll_sxyz(r: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Static-xyz Euler angles (yaw about z, pitch about y, roll about x) of R = Rz Ry Rx.
    At gimbal lock (cos pitch <= 4 eps) yaw is 0 and roll takes the whole rotation."""
    cy = np.sqrt(r[:, 0, 0] * r[:, 0, 0] + r[:, 1, 0] * r[:, 1, 0])
    lock = cy <= 4.0 * EPS
    yaw = np.where(lock, 0.0, np.arctan2(r[:, 1, 0], r[:, 0, 0]))
    pitch = np.arctan2(-r[:, 2, 0], cy)
    roll = np.where(lock, np.arctan2(-r[:, 1, 2], r[:, 1, 1]), np.arctan2(r[:, 2, 1], r[:, 2, 2]))
    return yaw, pitch, roll


def rot_z(a: NDArray[np.float64]) -> NDArray[np.float64]:
    c, s = np.cos(a), np.sin(a)
    r = np.zeros((np.size(a), 3, 3))
    r[:, 0, 0], r[:, 0, 1], r[:, 1, 0], r[:, 1, 1], r[:, 2, 2] = c, -s, s, c, 1.0
    return r


def from_poses(t: NDArray[np.float64], like: Trajectory, name: str | None = None) -> Trajectory:
    return Trajectory(like.stamps, t[:, :3, 3].copy(), matrix_to_quat_xyzw(t[:, :3, :3]),
                      name=like.name if name is None else name, frame_id=like.frame_id,
                      child_frame_id=like.child_frame_id)
