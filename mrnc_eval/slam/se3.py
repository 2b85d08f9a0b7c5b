"""Small SE(3)/SO(3) helpers for the SLAM (4x4 homogeneous matrices, rotation vectors)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def exp_so3(w: np.ndarray) -> np.ndarray:
    return Rotation.from_rotvec(w).as_matrix()


def make(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def inv(T: np.ndarray) -> np.ndarray:
    R = T[:3, :3]
    return make(R.T, -R.T @ T[:3, 3])


def apply(T: np.ndarray, p: np.ndarray) -> np.ndarray:
    return p @ T[:3, :3].T + T[:3, 3]


def delta_angle(T: np.ndarray) -> float:
    return float(np.linalg.norm(Rotation.from_matrix(T[:3, :3]).as_rotvec()))


def rpy(T: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(T[:3, :3]).as_euler("xyz")
