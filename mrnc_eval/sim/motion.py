"""Body motion with ground truth: the closed-loop trace (x, y, yaw at 1 kHz) lifted onto the
terrain (z, pitch and roll follow the ground). Positions and rotations at any time, plus
the kinematic derivatives an IMU measures."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from mrnc_eval.sim.scene import Terrain

BASE_HEIGHT_M = 0.6  # base_link above the ground contact


@dataclass(frozen=True)
class BodyMotion:
    t: np.ndarray  # (N,) s, uniform, from the closed loop
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray  # unwrapped
    terrain: Terrain

    def pose(self, times: np.ndarray) -> tuple[np.ndarray, Rotation]:
        """Positions (M, 3) and orientations of base_link in the map frame at `times` (s)."""
        x = np.interp(times, self.t, self.x)
        y = np.interp(times, self.t, self.y)
        yaw = np.interp(times, self.t, self.yaw)
        z = self.terrain.height(x, y) + BASE_HEIGHT_M
        gx, gy = self.terrain.gradient(x, y)
        forward = gx * np.cos(yaw) + gy * np.sin(yaw)
        left = -gx * np.sin(yaw) + gy * np.cos(yaw)
        pitch = -np.arctan(forward)  # REP-103: positive pitch = nose down
        roll = np.arctan(left)
        rot = Rotation.from_euler("ZYX", np.c_[yaw, pitch, roll])
        return np.c_[x, y, z], rot

    def imu_kinematics(self, times: np.ndarray, lever_arm: np.ndarray, h: float = 1e-3):
        """Specific force and angular rate (both in the body frame) of a point at `lever_arm`
        (m, body frame), by central differences of the exact pose (h in s)."""
        def point(ts):
            p, r = self.pose(ts)
            return p + r.apply(lever_arm), r

        p_m, _ = point(times - h)
        p_0, r_0 = point(times)
        p_p, r_p = point(times + h)
        acc_w = (p_p - 2 * p_0 + p_m) / (h * h)
        _, r_m = point(times - h)
        omega_b = (r_m.inv() * r_p).as_rotvec() / (2 * h)
        specific_force = r_0.inv().apply(acc_w + np.array([0.0, 0.0, 9.80665]))
        return specific_force, omega_b, p_0, r_0
