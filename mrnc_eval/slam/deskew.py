"""Deskew a sweep to its start time: rotation from the IMU track (LIO-SAM), translation from
a constant-velocity motion estimate (optional; LIO-SAM leaves it out)."""

from __future__ import annotations

import numpy as np

from mrnc_eval.slam.imu import ImuTrack


def deskew(points: np.ndarray, point_time: np.ndarray, stamp: float, track: ImuTrack | None,
           velocity_sensor: np.ndarray | None) -> np.ndarray:
    """Points (N, 3) measured at stamp + point_time, expressed in the sensor frame at `stamp`."""
    out = points.astype(np.float64)
    if track is not None:
        # quantise times to 1 ms: a few hundred distinct rotations instead of one per point
        tq = np.round(point_time.astype(np.float64), 3)
        uniq, inv = np.unique(tq, return_inverse=True)
        rots = track.rotation_between(stamp, stamp + uniq).as_matrix()
        out = np.einsum("nij,nj->ni", rots[inv.ravel()], out)
    if velocity_sensor is not None:
        out = out + point_time.astype(np.float64)[:, None] * velocity_sensor[None, :]
    return out
