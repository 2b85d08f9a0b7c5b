"""Alignment of an estimate to a reference (positions only, as evo).

Modes: none, se3 (Umeyama without scale), sim3, scale (Umeyama with scale, only the scale
applied), origin (first poses coincide), yaw (4-DoF: rotation about z + translation, for
gravity-aligned or GNSS references). `n_to_align` uses the first N matched poses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.errors import EvaluationError
from mrnc_eval.evaluation import lie

AlignMode = Literal["none", "se3", "sim3", "scale", "origin", "yaw"]
ALIGN_MODES = ("none", "se3", "sim3", "scale", "origin", "yaw")


@dataclass(frozen=True)
class Alignment:
    mode: str
    rotation: NDArray[np.float64]  # (3, 3)
    translation: NDArray[np.float64]  # (3,)
    scale: float

    def sim3(self) -> NDArray[np.float64]:
        """4x4 with c R in the rotation block (evo's alignment_transformation_sim3)."""
        t = np.eye(4)
        t[:3, :3] = self.scale * self.rotation
        t[:3, 3] = self.translation
        return t


def umeyama(x: NDArray[np.float64], y: NDArray[np.float64], with_scale: bool) -> tuple[NDArray, NDArray, float]:
    """R, t, c minimising sum |y - (c R x + t)|^2; x, y are (n, 3) matched positions."""
    n = x.shape[0]
    mx, my = x.mean(axis=0), y.mean(axis=0)
    xc, yc = x - mx, y - my
    sigma_x = np.einsum("ij,ij->", xc, xc) / n
    cov = yc.T @ xc / n
    u, d, vt = np.linalg.svd(cov)
    if np.count_nonzero(d > np.finfo(float).eps) < 2:
        raise EvaluationError("degenerate covariance rank: Umeyama alignment is not possible "
                              "(the matched positions are collinear or identical)")
    s = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0.0:
        s[2, 2] = -1.0
    r = u @ s @ vt
    c = float(np.trace(np.diag(d) @ s) / sigma_x) if with_scale else 1.0
    t = my - c * r @ mx
    return r, t, c


def yaw_align(x: NDArray[np.float64], y: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Rotation about z and translation minimising sum |y - (Rz x + t)|^2 (closed form)."""
    mx, my = x.mean(axis=0), y.mean(axis=0)
    xc, yc = x - mx, y - my
    num = np.sum(xc[:, 0] * yc[:, 1] - xc[:, 1] * yc[:, 0])
    den = np.sum(xc[:, 0] * yc[:, 0] + xc[:, 1] * yc[:, 1])
    if abs(num) < 1e-15 and abs(den) < 1e-15:
        raise EvaluationError("degenerate yaw alignment: the matched positions do not spread in the plane")
    r = lie.rot_z(np.array([np.arctan2(num, den)]))[0]
    return r, my - r @ mx


def estimate_alignment(ref_poses: NDArray, est_poses: NDArray, mode: str, n_to_align: int | None = None) -> Alignment:
    if mode not in ALIGN_MODES:
        raise EvaluationError(f"unknown alignment {mode!r}; choose one of {', '.join(ALIGN_MODES)}")
    n = ref_poses.shape[0] if n_to_align is None else int(n_to_align)
    if n < 1 or n > ref_poses.shape[0]:
        raise EvaluationError(f"n_to_align must be in 1..{ref_poses.shape[0]}, got {n_to_align}")
    x, y = est_poses[:n, :3, 3], ref_poses[:n, :3, 3]
    if mode == "none":
        return Alignment(mode, np.eye(3), np.zeros(3), 1.0)
    if mode == "origin":
        t = ref_poses[0] @ lie.inverse(est_poses[0])
        return Alignment(mode, t[:3, :3], t[:3, 3], 1.0)
    if mode == "yaw":
        if n < 2:
            raise EvaluationError("yaw alignment needs at least 2 matched poses")
        r, t = yaw_align(x, y)
        return Alignment(mode, r, t, 1.0)
    if n < 3:
        raise EvaluationError(f"{mode} alignment needs at least 3 matched poses, got {n}")
    r, t, c = umeyama(x, y, with_scale=mode in ("sim3", "scale"))
    if mode == "scale":
        return Alignment(mode, np.eye(3), np.zeros(3), c)
    return Alignment(mode, r, t, c)


def apply_alignment(est_poses: NDArray, a: Alignment) -> NDArray:
    """p' = c R p + t, R_i' = R R_i (left-multiplied, as evo)."""
    out = est_poses.copy()
    out[:, :3, :3] = a.rotation @ est_poses[:, :3, :3]
    out[:, :3, 3] = a.scale * est_poses[:, :3, 3] @ a.rotation.T + a.translation
    return out


def project_to_plane(poses: NDArray, plane: str) -> NDArray:
    """Flatten to a plane after the 3-D alignment: drop the normal coordinate and keep only
    the rotation about the normal (sxyz Euler angle), as evo's --project_to_plane."""
    axes = {"xy": 2, "xz": 1, "yz": 0}
    if plane not in axes:
        raise EvaluationError(f"plane must be xy, xz or yz, got {plane!r}")
    out = poses.copy()
    out[:, axes[plane], 3] = 0.0
    yaw, pitch, roll = lie.yaw_pitch_roll_sxyz(poses[:, :3, :3])
    if plane == "xy":
        out[:, :3, :3] = lie.rot_z(yaw)
    else:
        ang = pitch if plane == "xz" else roll
        c, s = np.cos(ang), np.sin(ang)
        r = np.zeros((ang.size, 3, 3))
        if plane == "xz":  # rotation about y
            r[:, 0, 0], r[:, 0, 2], r[:, 1, 1], r[:, 2, 0], r[:, 2, 2] = c, s, 1.0, -s, c
        else:  # rotation about x
            r[:, 0, 0], r[:, 1, 1], r[:, 1, 2], r[:, 2, 1], r[:, 2, 2] = 1.0, c, -s, s, c
        out[:, :3, :3] = r
    return out
