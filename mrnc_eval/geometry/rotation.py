"""Rotations as 3x3 matrices for the SLAM's run: quaternion <-> matrix, rotation vector exp/log,
roll-pitch-yaw, slerp. Pure numpy, so the `slam` command does not import scipy (~41 MB resident
and ~0.6 s of a cold start for a few small conversions per sweep; scipy's Rotation also costs
~20-40 us of object overhead per call, several calls a sweep). Each function takes one rotation
or a stack (..., 3, 3) / (..., 4) / (..., 3). Conventions: quaternions (x, y, z, w); roll-pitch-yaw
is R = Rz(yaw) Ry(pitch) Rx(roll) (extrinsic x-y-z, the same as intrinsic Z-Y-X). Checked
against scipy in tests/slam/test_rotation.py."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mrnc_eval.geometry.lie import matrix_to_quat_xyzw, nearest_orthonormal

F64 = NDArray[np.float64]
_SMALL = 1e-4  # rad (or |vector part| of a quaternion): below it the series replace sin/x, error < 1e-17


def quat_to_matrix(q: ArrayLike) -> F64:
    """(..., 4) xyzw quaternions (any norm > 0) -> (..., 3, 3) rotation matrices."""
    qa = np.asarray(q, dtype=np.float64)
    qa = qa / np.linalg.norm(qa, axis=-1, keepdims=True)
    x, y, z, w = qa[..., 0], qa[..., 1], qa[..., 2], qa[..., 3]
    out = np.empty((*qa.shape[:-1], 3, 3))
    out[..., 0, 0] = w * w + x * x - y * y - z * z
    out[..., 0, 1] = 2.0 * (x * y - z * w)
    out[..., 0, 2] = 2.0 * (x * z + y * w)
    out[..., 1, 0] = 2.0 * (x * y + z * w)
    out[..., 1, 1] = w * w - x * x + y * y - z * z
    out[..., 1, 2] = 2.0 * (y * z - x * w)
    out[..., 2, 0] = 2.0 * (x * z - y * w)
    out[..., 2, 1] = 2.0 * (y * z + x * w)
    out[..., 2, 2] = w * w - x * x - y * y + z * z
    return out


def matrix_to_quat(r: ArrayLike) -> F64:
    """(..., 3, 3) -> (..., 4) unit xyzw quaternions; a matrix off orthonormal by more than
    rounding is replaced by the nearest rotation first (`lie.nearest_orthonormal`)."""
    r = np.asarray(r, dtype=np.float64)
    if r.ndim == 2 and _orthonormal(m := r.tolist()):
        return np.array(_quat_of(m))
    flat = r.reshape(-1, 3, 3)
    return matrix_to_quat_xyzw(nearest_orthonormal(flat)).reshape(*r.shape[:-2], 4)


def _orthonormal(m: list[list[float]]) -> bool:
    """R R^T within `lie.nearest_orthonormal`'s tolerance of I (a single matrix, Python floats)."""
    for i in range(3):
        for j in range(i, 3):
            g = m[i][0] * m[j][0] + m[i][1] * m[j][1] + m[i][2] * m[j][2]
            if (abs(g - 1.0) > 1e-12 + 1e-5) if i == j else (abs(g) > 1e-12):
                return False
    return True


def _quat_of(m: list[list[float]]) -> tuple[float, float, float, float]:
    """Unit xyzw quaternion of one rotation matrix (Python floats): `lie.matrix_to_quat_xyzw`'s
    Shepperd cases, the same sign, ~20x faster than its array path for a single matrix."""
    trace = m[0][0] + m[1][1] + m[2][2]
    decision = (m[0][0], m[1][1], m[2][2], trace)
    c = max(range(4), key=decision.__getitem__)  # the first of equal maxima, as numpy's argmax
    q = [0.0, 0.0, 0.0, 0.0]
    if c == 3:
        q = [m[2][1] - m[1][2], m[0][2] - m[2][0], m[1][0] - m[0][1], 1.0 + trace]
    else:
        j, k = (c + 1) % 3, (c + 2) % 3
        q[c] = 1.0 - trace + 2.0 * m[c][c]
        q[j] = m[j][c] + m[c][j]
        q[k] = m[k][c] + m[c][k]
        q[3] = m[k][j] - m[j][k]
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return q[0] / n, q[1] / n, q[2] / n, q[3] / n


def exp(rotvec: ArrayLike) -> F64:
    """(..., 3) rotation vectors (axis * angle, rad) -> (..., 3, 3) matrices (Rodrigues)."""
    v = np.asarray(rotvec, dtype=np.float64)
    if v.ndim == 1:
        return _exp_one(*v.tolist())
    theta2 = np.einsum("...i,...i->...", v, v)
    theta = np.sqrt(theta2)
    small = theta < _SMALL
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta2 / 6.0, np.sin(safe) / safe)  # sin(t) / t
    b = np.where(small, 0.5 - theta2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))  # (1 - cos t) / t^2
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    out = np.empty((*v.shape[:-1], 3, 3))
    out[..., 0, 0] = 1.0 - b * (y * y + z * z)
    out[..., 1, 1] = 1.0 - b * (x * x + z * z)
    out[..., 2, 2] = 1.0 - b * (x * x + y * y)
    out[..., 0, 1] = b * x * y - a * z
    out[..., 1, 0] = b * x * y + a * z
    out[..., 0, 2] = b * x * z + a * y
    out[..., 2, 0] = b * x * z - a * y
    out[..., 1, 2] = b * y * z - a * x
    out[..., 2, 1] = b * y * z + a * x
    return out


def _exp_one(x: float, y: float, z: float) -> F64:
    """`exp` of one rotation vector with Python floats (the array path's overhead is ~15 us)."""
    theta2 = x * x + y * y + z * z
    if theta2 < _SMALL * _SMALL:
        a, b = 1.0 - theta2 / 6.0, 0.5 - theta2 / 24.0
    else:
        theta = math.sqrt(theta2)
        a, b = math.sin(theta) / theta, (1.0 - math.cos(theta)) / theta2
    return np.array([[1.0 - b * (y * y + z * z), b * x * y - a * z, b * x * z + a * y],
                     [b * x * y + a * z, 1.0 - b * (x * x + z * z), b * y * z - a * x],
                     [b * x * z - a * y, b * y * z + a * x, 1.0 - b * (x * x + y * y)]])


def log(r: ArrayLike) -> F64:
    """(..., 3, 3) matrices -> (..., 3) rotation vectors, angle in [0, pi] (through the quaternion:
    well conditioned at every angle, unlike acos of the trace)."""
    q = matrix_to_quat(r)
    if q.ndim == 1:
        return _log_one(*q.tolist())
    q = np.where(q[..., 3:4] < 0.0, -q, q)  # w >= 0: the short way round
    v, w = q[..., :3], q[..., 3]
    s = np.linalg.norm(v, axis=-1)
    small = s < _SMALL
    safe_s = np.where(small, 1.0, s)
    # angle = 2 atan2(s, w); rotvec = angle / s * v. Near 0 (w ~ 1): 2 atan(s / w) / s = (2 / w)(1 - x^2 / 3 + x^4 / 5)
    xw = np.where(small, s / np.where(w > 0.0, w, 1.0), 0.0)
    scale = np.where(small, 2.0 / np.where(w > 0.0, w, 1.0) * (1.0 - xw * xw / 3.0 + xw ** 4 / 5.0),
                     2.0 * np.arctan2(s, w) / safe_s)
    out: F64 = v * scale[..., None]
    return out


def _log_one(x: float, y: float, z: float, w: float) -> F64:
    """`log` of one unit quaternion with Python floats."""
    if w < 0.0:
        x, y, z, w = -x, -y, -z, -w
    s = math.sqrt(x * x + y * y + z * z)
    if s < _SMALL:
        xw = s / w
        scale = 2.0 / w * (1.0 - xw * xw / 3.0 + xw ** 4 / 5.0)
    else:
        scale = 2.0 * math.atan2(s, w) / s
    return np.array([x * scale, y * scale, z * scale])


def angle(r: ArrayLike) -> F64:
    """Rotation angle (rad, [0, pi]) of (..., 3, 3) matrices."""
    q = matrix_to_quat(r)
    out: F64 = 2.0 * np.arctan2(np.linalg.norm(q[..., :3], axis=-1), np.abs(q[..., 3]))
    return out


def rpy(r: ArrayLike) -> F64:
    """(..., 3, 3) -> (..., 3) [roll, pitch, yaw] (rad) with R = Rz(yaw) Ry(pitch) Rx(roll); pitch in
    [-pi/2, pi/2]. At pitch = +-pi/2 (gimbal lock) only roll - yaw or roll + yaw is defined: yaw = 0."""
    r = np.asarray(r, dtype=np.float64)
    c = np.hypot(r[..., 0, 0], r[..., 1, 0])  # cos(pitch) >= 0
    pitch = np.arctan2(-r[..., 2, 0], c)
    locked = c < 1e-12
    roll = np.where(locked, np.arctan2(-r[..., 1, 2], r[..., 1, 1]), np.arctan2(r[..., 2, 1], r[..., 2, 2]))
    yaw = np.where(locked, 0.0, np.arctan2(r[..., 1, 0], r[..., 0, 0]))
    return np.stack([roll, pitch, yaw], axis=-1)


def from_rpy(angles: ArrayLike) -> F64:
    """(..., 3) [roll, pitch, yaw] (rad) -> (..., 3, 3) R = Rz(yaw) Ry(pitch) Rx(roll)."""
    a = np.asarray(angles, dtype=np.float64)
    cr, sr = np.cos(a[..., 0]), np.sin(a[..., 0])
    cp, sp = np.cos(a[..., 1]), np.sin(a[..., 1])
    cy, sy = np.cos(a[..., 2]), np.sin(a[..., 2])
    out = np.empty((*a.shape[:-1], 3, 3))
    out[..., 0, 0] = cy * cp
    out[..., 0, 1] = cy * sp * sr - sy * cr
    out[..., 0, 2] = cy * sp * cr + sy * sr
    out[..., 1, 0] = sy * cp
    out[..., 1, 1] = sy * sp * sr + cy * cr
    out[..., 1, 2] = sy * sp * cr - cy * sr
    out[..., 2, 0] = -sp
    out[..., 2, 1] = cp * sr
    out[..., 2, 2] = cp * cr
    return out


def yaw_matrix(yaw: ArrayLike) -> F64:
    """(...,) yaw (rad) -> (..., 3, 3) rotations about z."""
    y = np.asarray(yaw, dtype=np.float64)
    return from_rpy(np.stack([np.zeros_like(y), np.zeros_like(y), y], axis=-1))


def slerp(r0: ArrayLike, r1: ArrayLike, a: float) -> F64:
    """The rotation a of the way from r0 to r1 (3x3 each) along the shortest arc: r0 exp(a log(r0^T r1))."""
    r0 = np.asarray(r0, dtype=np.float64)
    return np.asarray(r0 @ exp(a * log(r0.T @ np.asarray(r1, dtype=np.float64))), np.float64)
