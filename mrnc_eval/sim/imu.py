"""IMU model: ideal specific force and angular rate from the ground truth, in the IMU's own axes
at its mounting point, plus white noise and a bias random walk (continuous-time densities, see
ImuSimConfig for units). Discrete sigmas at rate f: white = density * sqrt(f), bias step =
walk * sqrt(1 / f)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mrnc_eval.data import ImuSeries
from mrnc_eval.sim.config import ImuSimConfig
from mrnc_eval.sim.trajectory import BodyTrajectory


@dataclass(frozen=True)
class ImuNoise:
    acc_noise_density: float  # m/s^2/sqrt(Hz)
    gyro_noise_density: float  # rad/s/sqrt(Hz)
    acc_bias_walk: float  # m/s^3/sqrt(Hz)
    gyro_bias_walk: float  # rad/s^2/sqrt(Hz)

    @classmethod
    def from_config(cls, cfg: ImuSimConfig) -> ImuNoise:
        return cls(cfg.acc_noise_density, cfg.gyro_noise_density, cfg.acc_bias_walk, cfg.gyro_bias_walk)

    def variances(self, rate_hz: float) -> tuple[float, float]:
        """Per-sample white-noise variances (acc m^2/s^4, gyro rad^2/s^2) for the message covariances."""
        return self.acc_noise_density ** 2 * rate_hz, self.gyro_noise_density ** 2 * rate_hz


def ideal_imu(traj: BodyTrajectory, times: np.ndarray, base_to_imu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free specific force (M, 3) m/s^2 and angular rate (M, 3) rad/s in the IMU frame."""
    f_b, w_b, _, _ = traj.imu_kinematics(times, base_to_imu[:3, 3])
    r_bi = base_to_imu[:3, :3]  # columns: IMU axes in base_link
    return f_b @ r_bi, w_b @ r_bi


def simulate_imu(traj: BodyTrajectory, times: np.ndarray, base_to_imu: np.ndarray, noise: ImuNoise,
                 rng: np.random.Generator, frame_id: str, *, initial_bias: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> ImuSeries:
    """Measured IMU at `times` (s, uniform) with white noise and a bias random walk from zero (or
    `initial_bias` = (acc m/s^2, gyro rad/s))."""
    acc, gyro = ideal_imu(traj, times, base_to_imu)
    n = times.size
    rate = 1.0 / float(np.median(np.diff(times))) if n > 1 else 100.0
    acc_b0, gyro_b0 = initial_bias if initial_bias is not None else (np.zeros(3), np.zeros(3))
    acc_bias = acc_b0 + np.cumsum(rng.normal(0.0, noise.acc_bias_walk / math.sqrt(rate), (n, 3)), axis=0)
    gyro_bias = gyro_b0 + np.cumsum(rng.normal(0.0, noise.gyro_bias_walk / math.sqrt(rate), (n, 3)), axis=0)
    acc = acc + acc_bias + rng.normal(0.0, noise.acc_noise_density * math.sqrt(rate), (n, 3))
    gyro = gyro + gyro_bias + rng.normal(0.0, noise.gyro_noise_density * math.sqrt(rate), (n, 3))
    return ImuSeries(np.asarray(times, float), acc, gyro, None, frame_id)
