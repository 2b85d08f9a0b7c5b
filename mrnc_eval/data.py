"""Typed numpy time series shared by readers, SLAM, control, evaluation and the simulator.

Conventions (used everywhere in the project):
- time stamps are float64 seconds (header stamps, never bag record times);
- positions in metres, angular rates in rad/s, accelerations in m/s^2;
- quaternions are (x, y, z, w), as in ROS messages and scipy;
- "left"/"right" are the robot's sides; positive yaw rate is a left turn (REP-103).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    import pandas as pd

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]


def _check_rows(name: str, n: int, **arrays: np.ndarray | None) -> None:
    for key, arr in arrays.items():
        if arr is not None and arr.shape[0] != n:
            raise ValueError(f"{name}: {key} has {arr.shape[0]} rows, stamps have {n}")


@dataclass(frozen=True)
class Trajectory:
    """Poses over time: stamps (N,), positions (N, 3), quaternions (N, 4) xyzw."""

    stamps: F64
    positions: F64
    quat_xyzw: F64
    name: str = ""
    frame_id: str = ""
    child_frame_id: str = ""
    # (N, 3, 3) rotation matrices exactly as read, when the source stores matrices (KITTI):
    # evaluation uses them unchanged, as evo does, instead of the orthonormal quat_xyzw.
    rotations: F64 | None = None

    def __post_init__(self) -> None:
        if self.positions.ndim != 2 or self.positions.shape[1] != 3:
            raise ValueError(f"Trajectory {self.name!r}: positions must be (N, 3)")
        if self.quat_xyzw.ndim != 2 or self.quat_xyzw.shape[1] != 4:
            raise ValueError(f"Trajectory {self.name!r}: quat_xyzw must be (N, 4)")
        if self.rotations is not None and self.rotations.shape[1:] != (3, 3):
            raise ValueError(f"Trajectory {self.name!r}: rotations must be (N, 3, 3)")
        _check_rows(f"Trajectory {self.name!r}", self.stamps.shape[0],
                    positions=self.positions, quat_xyzw=self.quat_xyzw, rotations=self.rotations)

    def __len__(self) -> int:
        return int(self.stamps.shape[0])

    def to_dataframe(self) -> pd.DataFrame:
        """One row per pose: t_s, x, y, z (m), qx, qy, qz, qw."""
        import pandas as pd

        data = np.column_stack([self.stamps, self.positions, self.quat_xyzw])
        return pd.DataFrame(data, columns=["t_s", "x", "y", "z", "qx", "qy", "qz", "qw"])


@dataclass(frozen=True)
class ImuSeries:
    """IMU samples in the IMU's own frame."""

    stamps: F64
    acc: F64  # (N, 3) m/s^2, specific force (gravity included, as a real IMU reports)
    gyro: F64  # (N, 3) rad/s
    orientation_xyzw: F64 | None = None  # (N, 4) for 9-axis IMUs, None for 6-axis
    frame_id: str = ""

    def __post_init__(self) -> None:
        _check_rows("ImuSeries", self.stamps.shape[0], acc=self.acc, gyro=self.gyro,
                    orientation_xyzw=self.orientation_xyzw)


@dataclass(frozen=True)
class Sweep:
    """One LiDAR sweep with no-return points already removed.

    `point_time` is seconds since `stamp` (the sweep start) or None when the cloud has
    no per-point time field. `ring` is the beam index and `column` the azimuth column
    (from the organised cloud layout) when known.
    """

    stamp: float
    points: F32  # (N, 3) in the sensor frame, m
    point_time: F32 | None = None  # (N,) s since stamp
    ring: NDArray[np.uint16] | None = None
    column: NDArray[np.uint32] | None = None
    intensity: F32 | None = None
    reflectivity: F32 | None = None
    frame_id: str = ""
    height: int = 1  # rows of the organised cloud (beams)
    width: int = 0  # columns of the organised cloud

    def __post_init__(self) -> None:
        _check_rows("Sweep", self.points.shape[0], point_time=self.point_time, ring=self.ring,
                    column=self.column, intensity=self.intensity, reflectivity=self.reflectivity)

    def __len__(self) -> int:
        return int(self.points.shape[0])


@dataclass(frozen=True)
class GnssSeries:
    """GNSS fixes (NO_FIX already dropped and counted) with their local ENU positions."""

    stamps: F64
    lla: F64  # (N, 3) latitude deg, longitude deg, altitude m (WGS-84)
    enu: F64  # (N, 3) east, north, up in m from `origin_lla`
    covariance: F64  # (N, 3, 3) ENU position covariance, m^2
    origin_lla: F64  # (3,)
    n_no_fix: int = 0
    frame_id: str = ""


@dataclass(frozen=True)
class SidePair:
    """A per-side signal: wheel speeds in m/s, or pump commands in RPM."""

    stamps: F64
    left: F64
    right: F64
    unit: str = ""

    def __post_init__(self) -> None:
        _check_rows("SidePair", self.stamps.shape[0], left=self.left, right=self.right)


@dataclass(frozen=True)
class Twists:
    """Body velocity commands (cmd_vel): forward speed m/s, yaw rate rad/s."""

    stamps: F64
    v: F64
    omega: F64


@dataclass(frozen=True)
class Waypoints:
    """A planned path in the map/odom frame."""

    xy: F64  # (N, 2) m
    stamp: float = 0.0
    frame_id: str = ""


@dataclass(frozen=True)
class StreamHealth:
    """How clean a time series was before sorting and de-duplication."""

    topic: str
    count: int
    duplicates: int = 0
    out_of_order: int = 0
    max_gap_s: float = 0.0
    notes: tuple[str, ...] = field(default_factory=tuple)
