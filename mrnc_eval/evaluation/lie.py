"""Vectorised SO(3)/SE(3) helpers on stacks of poses (N, 4, 4). Pure numpy."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.data import Trajectory

EPS = np.finfo(float).eps


def quat_xyzw_to_matrix(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N, 4) xyzw -> (N, 3, 3). Quaternions are normalised (scaled by sqrt(2/|q|^2)) as
    evo does; |q|^2 < 4 eps gives the identity."""
    q = np.asarray(q, dtype=float)
    n2 = np.einsum("ij,ij->i", q, q)
    ok = n2 >= 4.0 * EPS
    qs = np.where(ok[:, None], q * np.sqrt(2.0 / np.where(ok, n2, 1.0))[:, None], 0.0)
    x, y, z, w = qs[:, 0], qs[:, 1], qs[:, 2], qs[:, 3]
    r = np.empty((q.shape[0], 3, 3))
    r[:, 0, 0] = 1.0 - y * y - z * z
    r[:, 0, 1] = x * y - z * w
    r[:, 0, 2] = x * z + y * w
    r[:, 1, 0] = x * y + z * w
    r[:, 1, 1] = 1.0 - x * x - z * z
    r[:, 1, 2] = y * z - x * w
    r[:, 2, 0] = x * z - y * w
    r[:, 2, 1] = y * z + x * w
    r[:, 2, 2] = 1.0 - x * x - y * y
    r[~ok] = np.eye(3)
    return r


def matrix_to_quat_xyzw(r: NDArray[np.float64]) -> NDArray[np.float64]:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(r).as_quat()


def poses(traj: Trajectory) -> NDArray[np.float64]:
    """(N, 4, 4) homogeneous poses of a trajectory."""
    t = np.zeros((len(traj), 4, 4))
    t[:, :3, :3] = quat_xyzw_to_matrix(traj.quat_xyzw)
    t[:, :3, 3] = traj.positions
    t[:, 3, 3] = 1.0
    return t


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
    return np.matmul(a, b)


def rotation_angle(r: NDArray[np.float64]) -> NDArray[np.float64]:
    """|angle| (rad) of each rotation, through the quaternion: 2 atan2(|q_xyz|, |q_w|).

    More accurate than arccos((tr R - 1) / 2) for small angles (error ~eps/theta there).
    """
    q = matrix_to_quat_xyzw(r)
    return 2.0 * np.arctan2(np.linalg.norm(q[:, :3], axis=1), np.abs(q[:, 3]))


def yaw_pitch_roll_sxyz(r: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray]:
    """Static-xyz Euler angles (roll about x, pitch about y, yaw about z) of R = Rz Ry Rx."""
    yaw = np.arctan2(r[:, 1, 0], r[:, 0, 0])
    pitch = np.arctan2(-r[:, 2, 0], np.hypot(r[:, 0, 0], r[:, 1, 0]))
    roll = np.arctan2(r[:, 2, 1], r[:, 2, 2])
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
