"""Validation at the reader boundary: every stream is checked once, as it is read.

Each check gives a boolean "bad" mask per sample (non-finite values, quaternions that are not
unit norm, impossible latitudes, speeds or accelerations). The policy is the same for every
stream: a few bad samples are dropped and counted (a health note, shown by `info` and in the
result's warnings); when more than `max_bad_fraction` of a stream is bad, the stream is
refused with an InputError naming the topic and the first problem. So a NaN never reaches a
metric, and an all-NaN or all-zero-quaternion stream is an error, not a number.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from mrnc_eval.errors import InputError
from mrnc_eval.params import param


@dataclass(frozen=True)
class ValidationConfig:
    """Input validation: what is dropped, what is refused."""

    max_bad_fraction: float = param(
        0.05, "a stream with more bad samples than this fraction is refused; fewer are dropped and counted",
        ge=0.0, le=1.0)
    quat_norm_tolerance: float = param(
        0.01, "a quaternion whose norm differs from 1 by more than this is invalid (kept ones are normalised)",
        gt=0.0, le=0.5)
    max_abs_acceleration_mps2: float = param(
        400.0, "IMU linear acceleration beyond this (40 g, above any MEMS IMU range) is invalid", "m/s^2", gt=0.0)
    max_abs_angular_rate_rad_s: float = param(
        35.0, "IMU angular rate beyond this (2000 deg/s) is invalid", "rad/s", gt=0.0)
    max_abs_speed_mps: float = param(
        30.0, "wheel surface speeds, commanded speeds and odometry speeds beyond this are invalid", "m/s", gt=0.0)
    max_abs_altitude_m: float = param(
        20000.0, "GNSS altitudes beyond this are invalid", "m", gt=0.0)
    max_abs_position_m: float = param(
        1.0e7, "pose positions beyond this (further than the Earth's radius) are invalid", "m", gt=0.0)


Mask = npt.NDArray[np.bool_]  # one flag per sample
Floats = npt.NDArray[np.float64]


def non_finite(*arrays: npt.ArrayLike) -> Mask:
    """Per-sample mask: any value of the sample's row is NaN or infinite."""
    rows = [np.asarray(a, dtype=float) for a in arrays]
    bad = np.zeros(rows[0].shape[0], dtype=bool)
    for a in rows:
        bad |= ~np.isfinite(a.reshape(a.shape[0], -1)).all(axis=1)
    return bad


def beyond(values: npt.ArrayLike, limit: float) -> Mask:
    """Per-sample mask: some component's magnitude exceeds `limit` (NaN compares as not beyond)."""
    a = np.abs(np.asarray(values, dtype=float))
    with np.errstate(invalid="ignore"):
        return np.asarray((a.reshape(a.shape[0], -1) > limit).any(axis=1), dtype=bool)


def bad_quaternions(quat_xyzw: npt.ArrayLike, tolerance: float) -> Mask:
    """Per-sample mask: non-finite, or a norm further than `tolerance` from 1 (all-zero ones)."""
    q = np.asarray(quat_xyzw, dtype=float).reshape(-1, 4)
    with np.errstate(invalid="ignore", over="ignore"):  # inf/NaN/huge components are what we look for
        norm = np.linalg.norm(q, axis=1)
        return np.asarray(~np.isfinite(q).all(axis=1) | ~(np.abs(norm - 1.0) <= tolerance), dtype=bool)


MIN_QUAT_NORM = 1e-6  # below this a quaternion has no direction to normalise (an all-zero one)


def bad_poses(stamps: npt.ArrayLike, positions: npt.ArrayLike, quat_xyzw: npt.ArrayLike) -> tuple[Mask, str]:
    """The check every trajectory file and object passes (TUM, KITTI, EuRoC, the API's
    Trajectory): per-pose mask of non-finite stamps, positions or quaternions and quaternions
    that cannot be normalised (norm < MIN_QUAT_NORM: all-zero ones, which evo turns into the
    identity and so into 0 deg of error), and the first problem in words. A non-unit but
    normalisable quaternion is accepted and normalised, as evo does with such files; a log's
    stream is screened more strictly (`bad_quaternions`, io.validation.quat_norm_tolerance)."""
    t = np.asarray(stamps, dtype=float).reshape(-1)
    p = np.asarray(positions, dtype=float).reshape(-1, 3)
    q = np.asarray(quat_xyzw, dtype=float).reshape(-1, 4)
    if not t.shape[0] == p.shape[0] == q.shape[0]:
        return _bad_poses_rows(t, p, q)  # (raises as before)
    # Block by block: the same per-row answers, with temporaries of a block instead of ~42 MB for
    # 1e6 poses (q * q inside the norm), which two files read at once held together (issue 30).
    bad = np.empty(t.shape[0], dtype=bool)
    for k in range(0, t.shape[0], _ROWS):
        bad[k:k + _ROWS] = _bad_poses_rows(t[k:k + _ROWS], p[k:k + _ROWS], q[k:k + _ROWS])[0]
    if not bad.any():
        return bad, ""
    k = int(np.flatnonzero(bad)[0])
    return bad, _bad_poses_rows(t[k:k + 1], p[k:k + 1], q[k:k + 1])[1]


_ROWS = 1 << 13  # poses per block of bad_poses (small: each reading thread keeps its freed blocks)


def _bad_poses_rows(t: Floats, p: Floats, q: Floats) -> tuple[Mask, str]:
    bad_tp = ~np.isfinite(t) | ~np.isfinite(p).all(axis=1)
    with np.errstate(invalid="ignore", over="ignore"):
        norm = np.linalg.norm(q, axis=1)
        bad_q = ~np.isfinite(q).all(axis=1) | ~(norm >= MIN_QUAT_NORM)
    bad = np.asarray(bad_q | bad_tp, dtype=bool)
    if not bad.any():
        return bad, ""
    k = int(np.flatnonzero(bad)[0])
    what = ("non-finite stamp or position" if bad_tp[k] else
            f"quaternion of norm {norm[k]:.3g}, which has no rotation (zero or non-finite)")
    return bad, what


def normalised(quat_xyzw: npt.ArrayLike) -> Floats:
    q = np.asarray(quat_xyzw, dtype=float).reshape(-1, 4)
    return np.asarray(q / np.linalg.norm(q, axis=1, keepdims=True), dtype=float)


def bad_lat_lon(lla: npt.ArrayLike, max_abs_altitude_m: float) -> Mask:
    """Per-sample mask: latitude outside [-90, 90] deg, longitude outside [-180, 180] deg,
    altitude beyond the limit, or any of them non-finite."""
    a = np.asarray(lla, dtype=float).reshape(-1, 3)
    with np.errstate(invalid="ignore"):
        ok = (np.abs(a[:, 0]) <= 90.0) & (np.abs(a[:, 1]) <= 180.0) & (np.abs(a[:, 2]) <= max_abs_altitude_m)
    return np.asarray(~ok, dtype=bool)


def screen(path: str, topic: str, checks: dict[str, Mask], cfg: ValidationConfig) -> tuple[Mask, str]:
    """Apply the policy to named bad-sample masks. Returns (keep mask, health note or "").

    Raises InputError when the stream is empty after screening or more than
    `cfg.max_bad_fraction` of its samples are bad."""
    n = len(next(iter(checks.values()))) if checks else 0
    bad = np.zeros(n, dtype=bool)
    counts: list[str] = []
    for reason, mask in checks.items():
        k = int(np.count_nonzero(mask & ~bad))
        if k:
            counts.append(f"{k} {reason}")
        bad |= mask
    n_bad = int(np.count_nonzero(bad))
    if n_bad == 0:
        return ~bad, ""
    detail = ", ".join(counts)
    if n_bad == n or n_bad > cfg.max_bad_fraction * n:
        raise InputError(path, f"stream refused: {n_bad} of {n} samples invalid ({detail}); more than "
                         f"io.validation.max_bad_fraction = {cfg.max_bad_fraction:g}", topic=topic)
    return ~bad, f"{n_bad} of {n} samples dropped as invalid ({detail})"
