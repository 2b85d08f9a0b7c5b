"""imu_units: whether an IMU's accelerometer reads in m/s^2, as sensor_msgs/Imu requires, or in g.

Some drivers write g. Read as m/s^2, gravity then looks like 1 m/s^2: the attitude, the
preintegration and the stationary-stretch detection all go wrong (the yard circle: 8.8 m online APE
against 0.02 m, and a warning blaming the LiDAR mount). On a ground vehicle gravity dominates the
specific force, so its median magnitude over the log tells the unit."""

from __future__ import annotations

import numpy as np

TOLERANCE = 0.3  # the median |specific force| within this fraction of gravity's magnitude (in either unit)
STANDARD_GRAVITY = 9.80665  # m/s^2 in 1 g, by definition (the unit, not the local gravity)


def accelerometer_scale(acc: np.ndarray, gravity_mps2: float) -> tuple[float | None, float]:
    """(factor to m/s^2, median |specific force| as read): 1 when the median magnitude is within
    TOLERANCE of gravity_mps2 (the local gravity), STANDARD_GRAVITY when it is within TOLERANCE of 1
    (g), else None."""
    acc = np.asarray(acc, float)
    finite = np.all(np.isfinite(acc), axis=1) if acc.ndim == 2 and acc.shape[0] else np.zeros(0, bool)
    if not finite.any():
        return None, float("nan")
    median = float(np.median(np.linalg.norm(acc[finite], axis=1)))
    if abs(median / gravity_mps2 - 1.0) <= TOLERANCE:
        return 1.0, median
    if abs(median - 1.0) <= TOLERANCE:
        return STANDARD_GRAVITY, median
    return None, median
