"""Alignment of an estimate to a reference (positions only, as evo).

Modes: none, se3 (Umeyama without scale), sim3, scale (Umeyama with scale, only the scale
applied), origin (first poses coincide), yaw (4-DoF: rotation about z + translation, for
gravity-aligned or GNSS references). `n_to_align` uses the first N matched poses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.data import Trajectory
from mrnc_eval.errors import EvaluationError
from mrnc_eval.evaluation import sync
from mrnc_eval.evaluation.modes import AlignMode, parse_choice
from mrnc_eval.geometry import lie
from mrnc_eval.geometry.point_fit import CHUNK, umeyama, yaw_align

__all__ = ["Alignment", "align_positions", "align_rotations", "estimate_alignment", "umeyama", "yaw_align"]


@dataclass(frozen=True)
class Alignment:
    """A rigid (or similarity) alignment of the estimate onto the reference."""

    mode: AlignMode
    rotation: NDArray[np.float64]  # (3, 3)
    translation: NDArray[np.float64]  # (3,)
    scale: float
    n_to_align: int | None = None  # the first N matched poses were used (None: all)

    def summary(self) -> dict[str, object]:
        """What a reader needs to reproduce the numbers: mode, poses used, scale, the 4x4 applied."""
        return {"mode": str(self.mode), "n_to_align": self.n_to_align, "scale": self.scale,
                "transform": self.sim3().tolist()}

    def sim3(self) -> NDArray[np.float64]:
        """4x4 with c R in the rotation block (evo's alignment_transformation_sim3)."""
        t = np.eye(4)
        t[:3, :3] = self.scale * self.rotation
        t[:3, 3] = self.translation
        return t


def estimate_alignment(ref: Trajectory, est: Trajectory, mode: AlignMode | str,
                       n_to_align: int | None = None) -> Alignment:
    """Alignment of the matched estimate onto the matched reference (same length, paired)."""
    mode = parse_choice(AlignMode, mode, "alignment")
    n = len(ref) if n_to_align is None else int(n_to_align)
    if n < 1 or n > len(ref):
        raise EvaluationError(f"n_to_align must be in 1..{len(ref)}, got {n_to_align}")
    if mode is AlignMode.none:
        return Alignment(mode, np.eye(3), np.zeros(3), 1.0)
    if mode is AlignMode.origin:  # T = Q_0 P_0^-1: the first poses coincide
        q0, p0 = lie.poses(sync.take(ref, np.array([0])))[0], lie.poses(sync.take(est, np.array([0])))[0]
        t = q0 @ lie.inverse(p0)
        return Alignment(mode, t[:3, :3], t[:3, 3], 1.0)
    x, y = est.positions[:n], ref.positions[:n]
    if mode is AlignMode.yaw:
        if n < 2:
            raise EvaluationError("yaw alignment needs at least 2 matched poses")
        r, t = yaw_align(x, y)
        return Alignment(mode, r, t, 1.0, n_to_align)
    if n < 3:
        raise EvaluationError(f"{mode} alignment needs at least 3 matched poses, got {n}")
    r, t, c = umeyama(x, y, with_scale=mode in (AlignMode.sim3, AlignMode.scale))
    if mode is AlignMode.scale:
        return Alignment(mode, np.eye(3), np.zeros(3), c, n_to_align)
    return Alignment(mode, r, t, c, n_to_align)


def align_positions(xyz: NDArray[np.float64], a: Alignment) -> NDArray[np.float64]:
    """p' = c R p + t (scale first, then the rigid part, as evo)."""
    if a.mode is AlignMode.none:
        return xyz
    out = np.empty((xyz.shape[0], 3))
    r, t = a.rotation, a.translation
    for k in range(0, out.shape[0], CHUNK):  # by columns, in blocks: a (n, 3) @ (3, 3) BLAS call costs
        x, y, z = (a.scale * xyz[k:k + CHUNK, j] for j in range(3))  # ~20x more (threads, strides)
        for i in range(3):
            out[k:k + CHUNK, i] = r[i, 0] * x + r[i, 1] * y + r[i, 2] * z + t[i]
    return out


def align_rotations(rot: NDArray[np.float64], a: Alignment) -> NDArray[np.float64]:
    """R_i' = R R_i (left-multiplied, as evo)."""
    if a.mode in (AlignMode.none, AlignMode.scale):
        return rot
    out: NDArray[np.float64] = np.matmul(a.rotation, rot)
    return out


_PLANE_NORMAL = {"xy": 2, "xz": 1, "yz": 0}


def check_plane(plane: str | None) -> None:
    if plane is not None and plane not in _PLANE_NORMAL:
        raise EvaluationError(f"plane must be xy, xz or yz, got {plane!r}")


def project_positions(xyz: NDArray[np.float64], plane: str) -> NDArray[np.float64]:
    """Drop the coordinate along the plane normal (z = 0 for xy)."""
    check_plane(plane)
    out = xyz.copy()
    out[:, _PLANE_NORMAL[plane]] = 0.0
    return out


def project_rotations(rot: NDArray[np.float64], plane: str) -> NDArray[np.float64]:
    """Keep only the rotation about the plane normal (its static-xyz Euler angle), as evo's
    --project_to_plane; applied after the 3-D alignment, so it is not an SE(2) alignment."""
    check_plane(plane)
    yaw, pitch, roll = lie.yaw_pitch_roll_sxyz(rot)
    if plane == "xy":
        return lie.rot_z(yaw)
    ang = pitch if plane == "xz" else roll
    c, s = np.cos(ang), np.sin(ang)
    r = np.zeros((ang.size, 3, 3))
    if plane == "xz":  # rotation about y
        r[:, 0, 0], r[:, 0, 2], r[:, 1, 1], r[:, 2, 0], r[:, 2, 2] = c, s, 1.0, -s, c
    else:  # rotation about x
        r[:, 0, 0], r[:, 1, 1], r[:, 1, 2], r[:, 2, 1], r[:, 2, 2] = 1.0, c, -s, s, c
    return r
