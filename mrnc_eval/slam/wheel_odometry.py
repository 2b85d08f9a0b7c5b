"""Wheel odometry as a relative-pose factor between keyframes (graph #1): the odom -> base_link
track interpolated at two keyframe stamps, carried into the LiDAR frame through the base -> LiDAR
extrinsic, with a skid-steer noise model (forward and yaw errors grow with the distance driven and
the angle turned; lateral motion is nearly non-holonomic; z, roll and pitch are left to the LiDAR)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrnc_eval.errors import ProcessingError
from mrnc_eval.geometry import rotation, se3
from mrnc_eval.slam.config import WheelOdomConfig


@dataclass(frozen=True, kw_only=True)
class WheelTrack:
    """odom -> base_link poses: stamps (N,) s, positions (N, 3) m, quaternions (N, 4) xyzw."""

    stamps: np.ndarray
    positions: np.ndarray
    quat_xyzw: np.ndarray

    def covers(self, t0: float, t1: float) -> bool:
        return bool(self.stamps.size > 1 and self.stamps[0] <= min(t0, t1) and max(t0, t1) <= self.stamps[-1])

    def pose_at(self, t: float) -> np.ndarray:
        """4x4 pose at t: positions linear, rotation slerped between the neighbouring samples."""
        if not self.covers(t, t):
            raise ProcessingError(f"wheel odometry does not cover t = {t:.3f} s")
        i = int(np.clip(np.searchsorted(self.stamps, t) - 1, 0, self.stamps.size - 2))
        t0, t1 = self.stamps[i], self.stamps[i + 1]
        a = 0.0 if t1 <= t0 else (t - t0) / (t1 - t0)
        p = (1 - a) * self.positions[i] + a * self.positions[i + 1]
        r0, r1 = rotation.quat_to_matrix(self.quat_xyzw[i:i + 2])
        return se3.make(rotation.slerp(r0, r1, a), p)


def base_velocity(track: WheelTrack, t: float, half_window_s: float = 0.05) -> np.ndarray | None:
    """base_link velocity (m/s, base_link axes) at t: central difference over +-half_window_s,
    rotated into the frame at t; None outside the odometry span."""
    t0, t1 = t - half_window_s, t + half_window_s
    if not track.covers(t0, t1):
        return None
    p0, p1 = track.pose_at(t0)[:3, 3], track.pose_at(t1)[:3, 3]
    return np.asarray(track.pose_at(t)[:3, :3].T @ (p1 - p0) / (t1 - t0), np.float64)


def relative_motion(track: WheelTrack, t0: float, t1: float, base_to_sensor: np.ndarray) -> np.ndarray:
    """The LiDAR frame's motion from t0 to t1 (4x4, in the LiDAR frame at t0) by the wheels:
    B^-1 (W0^-1 W1) B, B = the LiDAR pose in base_link."""
    rel_base = se3.inv(track.pose_at(t0)) @ track.pose_at(t1)
    return np.asarray(se3.inv(base_to_sensor) @ rel_base @ base_to_sensor, np.float64)


def base_sigmas(rel_base: np.ndarray, cfg: WheelOdomConfig) -> np.ndarray:
    """1-sigma errors of a base_link relative motion, [roll, pitch, yaw (rad), x, y, z (m)] in
    base_link: forward and lateral grow with the distance driven, yaw with the angle turned (on a
    straight line both sides turn alike), z, roll and pitch loose (planar odometry)."""
    dist = float(np.linalg.norm(rel_base[:2, 3]))
    turned = abs(float(se3.rpy(rel_base)[2]))
    return np.array([cfg.tilt_sigma_rad, cfg.tilt_sigma_rad, cfg.yaw_fraction * turned + cfg.yaw_floor_rad,
                     cfg.forward_fraction * dist + cfg.forward_floor_m,
                     cfg.lateral_fraction * dist + cfg.lateral_floor_m, cfg.z_sigma_m])


def adjoint(T: np.ndarray) -> np.ndarray:
    """6x6 adjoint of T for tangent vectors ordered [rot, trans] (gtsam's Pose3)."""
    R, t = T[:3, :3], T[:3, 3]
    hat = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    return np.block([[R, np.zeros((3, 3))], [hat @ R, R]])


def sensor_covariance(rel_base: np.ndarray, base_to_sensor: np.ndarray, cfg: WheelOdomConfig) -> np.ndarray:
    """Covariance (6x6, [rot, trans], gtsam's tangent of the LiDAR-frame relative pose) of the
    wheel motion: the base_link sigmas carried by Ad(B^-1), since B^-1 D exp(x) B = (B^-1 D B) exp(Ad(B^-1) x)."""
    ad = adjoint(se3.inv(base_to_sensor))
    return np.asarray(ad @ np.diag(base_sigmas(rel_base, cfg) ** 2) @ ad.T, np.float64)


def wheel_factor(track: WheelTrack, t0: float, t1: float, base_to_sensor: np.ndarray,
                 cfg: WheelOdomConfig) -> tuple[np.ndarray, np.ndarray] | None:
    """(relative LiDAR pose, covariance) between keyframes at t0 and t1; None when the wheel
    odometry does not cover both stamps."""
    if not track.covers(t0, t1):
        return None
    rel = relative_motion(track, t0, t1, base_to_sensor)
    rel_base = base_to_sensor @ rel @ se3.inv(base_to_sensor)
    return rel, sensor_covariance(rel_base, base_to_sensor, cfg)


def blend_planar(tilted: np.ndarray, planar: np.ndarray) -> np.ndarray:
    """A map pose with z, roll and pitch of `tilted` and x, y and yaw (ZYX Euler) of `planar`."""
    roll, pitch, _ = rotation.rpy(tilted[:3, :3])
    yaw = rotation.rpy(planar[:3, :3])[2]
    rot = rotation.from_rpy([roll, pitch, yaw])
    return se3.make(rot, np.r_[planar[:2, 3], tilted[2, 3]])
