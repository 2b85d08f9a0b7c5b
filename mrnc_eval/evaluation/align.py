"""Alignment of an estimate to a reference (positions only, as evo).

Modes: none, se3 (Umeyama without scale), sim3, scale (Umeyama with scale, only the scale
applied), origin (first poses coincide), yaw (4-DoF: rotation about z + translation, for
gravity-aligned or GNSS references). `n_to_align` uses the first N matched poses.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.data import F64, Trajectory
from mrnc_eval.errors import EvaluationError
from mrnc_eval.evaluation import sync
from mrnc_eval.evaluation.modes import AlignMode, parse_choice
from mrnc_eval.geometry import lie

_kernels: ModuleType | None
try:  # the one-pass C loops (evaluation/_kernels.c, built by setup.py); numpy below gives the same bits
    from mrnc_eval.evaluation import _kernels
except ImportError:  # pragma: no cover - a build without a C compiler
    _kernels = None


@dataclass(frozen=True)
class Alignment:
    mode: AlignMode
    rotation: NDArray[np.float64]  # (3, 3)
    translation: NDArray[np.float64]  # (3,)
    scale: float

    def sim3(self) -> NDArray[np.float64]:
        """4x4 with c R in the rotation block (evo's alignment_transformation_sim3)."""
        t = np.eye(4)
        t[:3, :3] = self.scale * self.rotation
        t[:3, 3] = self.translation
        return t


CHUNK = 1 << 16  # rows per block of the sequential sums: ~1.5 MB of temporaries


def _sequential_sum(rows: NDArray[np.float64]) -> NDArray[np.float64]:
    """Column sums of (n, k) added one row after the other (what mean(axis=0) does on a
    C-ordered array), in blocks: the same bits for any memory layout, no full-size copy."""
    acc = np.zeros(rows.shape[1])
    for k in range(0, rows.shape[0], CHUNK):
        block = np.array(rows[k:k + CHUNK].T, order="C")  # one contiguous row per column
        block[:, 0] += acc  # carry the running sum in: still strictly sequential
        acc = np.cumsum(block, axis=1)[:, -1]
    return acc


def _sequential_outer_sum(y: F64, my: F64, x: F64, mx: F64) -> F64:
    """sum_i (y_i - my) (x_i - mx)^T added one point after the other, as evo's loop does
    (cumsum is sequential, sum is pairwise). A BLAS product rounds differently, and for nearly
    collinear paths the SVD turns that 1e-16 into 1e-12 in R; this order gives evo's bits.
    Centred in blocks: the same bits as centring the whole array first, without its copy."""
    products = np.empty((9, min(CHUNK, y.shape[0])))
    acc = np.zeros(9)
    for k in range(0, y.shape[0], CHUNK):
        yc = np.array(y[k:k + CHUNK].T, order="C") - my[:, None]
        xk = np.array(x[k:k + CHUNK].T, order="C") - mx[:, None]
        p = products[:, :yc.shape[1]]
        for a in range(3):
            for b in range(3):
                np.multiply(yc[a], xk[b], out=p[3 * a + b])
        p[:, 0] += acc
        acc = np.cumsum(p, axis=1)[:, -1]
    return acc.reshape(3, 3)


def umeyama(x: F64, y: F64, with_scale: bool) -> tuple[F64, F64, float]:
    """R, t, c minimising sum |y - (c R x + t)|^2; x, y are (n, 3) matched positions
    (Umeyama 1991, eqs. 34-43; same operation order as evo, so the same bits). Memory: small
    blocks, plus with scale one (n, 3) array (the centred x, whose norm BLAS takes in one piece)."""
    n = x.shape[0]
    if _kernels is not None:  # 1e6 points: ~5 ms instead of ~75 ms
        mx, my = np.array(_kernels.column_sums(x)) / n, np.array(_kernels.column_sums(y)) / n
        outer = np.array(_kernels.centred_outer_sum(y, tuple(my), x, tuple(mx))).reshape(3, 3)
    else:
        mx, my = _sequential_sum(x) / n, _sequential_sum(y) / n
        outer = _sequential_outer_sum(y, my, x, mx)
    cov = np.multiply(1.0 / n, outer)
    u, d, vt = np.linalg.svd(cov)
    if np.count_nonzero(d > np.finfo(float).eps) < 2:
        raise EvaluationError("degenerate covariance rank: Umeyama alignment is not possible "
                              "(the matched positions are collinear or identical)")
    s = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0.0:
        s[2, 2] = -1.0
    r = u.dot(s).dot(vt)
    c = 1.0
    if with_scale:
        sigma_x = 1.0 / n * np.linalg.norm(np.subtract(x, mx, order="C")) ** 2
        c = float(1.0 / sigma_x * np.trace(np.diag(d).dot(s)))
    t = my - np.multiply(c, r.dot(mx))
    return r, t, c


def yaw_align(x: NDArray[np.float64], y: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rotation about z and translation minimising sum |y - (Rz x + t)|^2 (closed form)."""
    mx, my = x.mean(axis=0), y.mean(axis=0)
    xc, yc = x - mx, y - my
    num = np.sum(xc[:, 0] * yc[:, 1] - xc[:, 1] * yc[:, 0])
    den = np.sum(xc[:, 0] * yc[:, 0] + xc[:, 1] * yc[:, 1])
    if abs(num) < 1e-15 and abs(den) < 1e-15:
        raise EvaluationError("degenerate yaw alignment: the matched positions do not spread in the plane")
    r = lie.rot_z(np.array([np.arctan2(num, den)]))[0]
    return r, my - r @ mx


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
        return Alignment(mode, r, t, 1.0)
    if n < 3:
        raise EvaluationError(f"{mode} alignment needs at least 3 matched poses, got {n}")
    r, t, c = umeyama(x, y, with_scale=mode in (AlignMode.sim3, AlignMode.scale))
    if mode is AlignMode.scale:
        return Alignment(mode, np.eye(3), np.zeros(3), c)
    return Alignment(mode, r, t, c)


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
