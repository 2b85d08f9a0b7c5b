"""Small SE(3)/SO(3) helpers for the SLAM (4x4 homogeneous matrices, rotation vectors).
Pose matrices are assembled by geometry.lie.homogeneous, the project's one builder."""

from __future__ import annotations

import numpy as np

from mrnc_eval.geometry import rotation
from mrnc_eval.geometry.lie import homogeneous


def exp_so3(w: np.ndarray) -> np.ndarray:
    return rotation.exp(w)


def make(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """4x4 pose [R t; 0 1]."""
    return homogeneous(R, t)


def inv(T: np.ndarray) -> np.ndarray:
    R = T[:3, :3]
    return make(R.T, -R.T @ T[:3, 3])


def apply(T: np.ndarray, p: np.ndarray) -> np.ndarray:
    return np.asarray(p @ T[:3, :3].T + T[:3, 3], np.float64)


def delta_angle(T: np.ndarray) -> float:
    return float(rotation.angle(T[:3, :3]))


def rpy(T: np.ndarray) -> np.ndarray:
    return rotation.rpy(T[:3, :3])
