"""Closed-form fits of matched point sets: Umeyama (rotation, translation, optional scale) and
the 4-DoF yaw fit (rotation about z + translation). Shared by trajectory alignment
(evaluation/align.py) and the SLAM's ENU -> map alignment (slam/gnss.py), as evo keeps
umeyama_alignment in its core geometry."""

from __future__ import annotations

from types import ModuleType

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.data import F64
from mrnc_eval.errors import EvaluationError
from mrnc_eval.geometry import lie

_kernels: ModuleType | None
try:  # the one-pass C loops (geometry/_kernels.c, built by setup.py); the numpy below gives the same bits
    from mrnc_eval.geometry import _kernels
except ImportError:  # pragma: no cover - a build without a C compiler
    _kernels = None

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
