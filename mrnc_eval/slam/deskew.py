"""Deskew a sweep to its start time: rotation from the raw-gyro IMU track (LIO-SAM), translation
from a constant-velocity motion estimate (optional; LIO-SAM leaves it out)."""

from __future__ import annotations

import numpy as np

from mrnc_eval.slam import _prep_kernels
from mrnc_eval.slam.imu import ImuTrack

QUANTUM_S = 1e-3  # rotations tabulated per millisecond: < 0.001 deg error at 1 rad/s


def deskew(points: np.ndarray, point_time: np.ndarray, stamp: float, track: ImuTrack | None,
           velocity_sensor: np.ndarray | None, accel_sensor: np.ndarray | None = None) -> np.ndarray:
    """Points (N, 3) measured at stamp + point_time (s), expressed in the sensor frame at `stamp`;
    the sensor moved by v t + a t^2 / 2 (velocity m/s and a constant acceleration m/s^2 over the
    sweep, sensor axes at `stamp`) by point time t."""
    t = np.ascontiguousarray(point_time, dtype=np.float64)
    out = np.empty((points.shape[0], 3))
    if t.size == 0:
        return out
    t0, t1 = float(t.min()), float(t.max())
    n = int(np.floor((t1 - t0) / QUANTUM_S + 0.5)) + 1
    if track is not None:
        table = track.rotation_between(stamp, stamp + t0 + QUANTUM_S * np.arange(n))
    else:
        table = np.broadcast_to(np.eye(3), (1, 3, 3)).copy()
    v = np.zeros(3) if velocity_sensor is None else np.asarray(velocity_sensor, float)
    acc = np.zeros(3) if accel_sensor is None else np.asarray(accel_sensor, float)
    # out_i = R_k p_i + v t_i + a t_i^2 / 2, R_k the table's rotation nearest t_i - t0 (one per QUANTUM_S = 1 ms)
    _prep_kernels.deskew_apply(np.ascontiguousarray(points, dtype=np.float64), t, t0,
                               np.ascontiguousarray(table, dtype=np.float64), tuple(v), tuple(acc), out)
    return out
