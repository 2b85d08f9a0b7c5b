"""IMU model: ideal specific force and angular rate from the ground truth, in the IMU's own axes
at its mounting point, plus white noise and a bias random walk (continuous-time densities, see
ImuSimConfig for units). Discrete sigmas at rate f: white = density * sqrt(f), bias step =
walk * sqrt(1 / f). The field profile (`field_imu`) adds turn-on biases, engine vibration,
saturation, quantisation and dropped samples."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mrnc_eval.data import ImuSeries
from mrnc_eval.sim.config import FieldImuConfig, ImuSimConfig
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


@dataclass(frozen=True)
class FieldImuSamples:
    """What the field IMU delivers at its true sample times (before the clock model stamps them)."""

    times: np.ndarray  # (M,) s, true sample times (dropped samples removed)
    acc: np.ndarray  # (M, 3) m/s^2
    gyro: np.ndarray  # (M, 3) rad/s
    acc_turn_on_bias: np.ndarray  # (3,) m/s^2, for tests
    gyro_turn_on_bias: np.ndarray  # (3,) rad/s


def vibration(times: np.ndarray, lines_hz: tuple[float, ...], rms: float, rng: np.random.Generator) -> np.ndarray:
    """(M, 3) sum of sinusoids at `lines_hz` with random phases per axis and line, `rms` per axis
    over all lines (each line's amplitude sqrt(2 / n_lines) * rms). Sampled without
    anti-aliasing, as an IMU without a matching low-pass filter does."""
    out = np.zeros((np.asarray(times).size, 3))
    if rms <= 0 or not lines_hz:
        return out
    amp = rms * math.sqrt(2.0 / len(lines_hz))
    for f in lines_hz:
        phase = rng.uniform(0.0, 2 * np.pi, 3)
        out += amp * np.sin(2 * np.pi * f * np.asarray(times, float)[:, None] + phase)
    return out


def field_imu(traj: BodyTrajectory, times: np.ndarray, base_to_imu: np.ndarray, cfg: FieldImuConfig,
              rng: np.random.Generator) -> FieldImuSamples:
    """A consumer MEMS IMU on a running diesel machine, sampled at the true `times` (s, uniform)."""
    acc, gyro = ideal_imu(traj, times, base_to_imu)
    return imu_errors(acc, gyro, times, cfg, rng)


def imu_errors(acc: np.ndarray, gyro: np.ndarray, times: np.ndarray, cfg: FieldImuConfig,
               rng: np.random.Generator) -> FieldImuSamples:
    """Ideal (M, 3) specific force (m/s^2) and rate (rad/s) at `times` (s, uniform) + turn-on
    bias + bias random walk + white noise + engine vibration, then saturated at the full-scale
    range, quantised to the LSB, and a few samples dropped."""
    n = times.size
    rate = 1.0 / float(np.median(np.diff(times))) if n > 1 else 100.0
    acc_b0 = rng.normal(0.0, cfg.acc_turn_on_bias, 3)
    gyro_b0 = rng.normal(0.0, cfg.gyro_turn_on_bias, 3)
    acc = acc + acc_b0 + np.cumsum(rng.normal(0.0, cfg.acc_bias_walk / math.sqrt(rate), (n, 3)), axis=0)
    gyro = gyro + gyro_b0 + np.cumsum(rng.normal(0.0, cfg.gyro_bias_walk / math.sqrt(rate), (n, 3)), axis=0)
    acc += rng.normal(0.0, cfg.acc_noise_density * math.sqrt(rate), (n, 3))
    gyro += rng.normal(0.0, cfg.gyro_noise_density * math.sqrt(rate), (n, 3))
    acc += vibration(times, cfg.vibration_hz, cfg.vibration_acc_rms, rng)
    gyro += vibration(times, cfg.vibration_hz, cfg.vibration_gyro_rms, rng)
    acc = _quantise(np.clip(acc, -cfg.acc_range, cfg.acc_range), cfg.acc_lsb)
    gyro = _quantise(np.clip(gyro, -cfg.gyro_range, cfg.gyro_range), cfg.gyro_lsb)
    keep = rng.random(n) >= cfg.drop_probability
    return FieldImuSamples(np.asarray(times, float)[keep], acc[keep], gyro[keep], acc_b0, gyro_b0)


def _quantise(x: np.ndarray, lsb: float) -> np.ndarray:
    return np.round(x / lsb) * lsb if lsb > 0 else x
