"""GNSS receiver model: the antenna's true position (ENU about the configured geodetic origin,
exactly converted to WGS-84), white noise with the reported covariance, NO_FIX dropouts (status
-1) and an optional multipath jump (a horizontal offset held over an interval)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrnc_eval.geodesy import enu_to_lla
from mrnc_eval.sim.config import GnssSimConfig
from mrnc_eval.sim.trajectory import BodyTrajectory

STATUS_FIX, STATUS_NO_FIX = 0, -1  # sensor_msgs/NavSatStatus


@dataclass(frozen=True)
class GnssFixes:
    stamps: np.ndarray  # (N,) s
    lla: np.ndarray  # (N, 3) deg, deg, m
    covariance: np.ndarray  # (N, 3, 3) m^2, ENU
    status: np.ndarray  # (N,) int
    true_enu: np.ndarray  # (N, 3) m, antenna truth (for tests)


def simulate_gnss(traj: BodyTrajectory, times: np.ndarray, base_to_antenna: np.ndarray, cfg: GnssSimConfig,
                  rng: np.random.Generator) -> GnssFixes:
    p, r = traj.pose(times)
    true_enu = p + r.apply(base_to_antenna[:3, 3])
    sigma = np.array([cfg.sigma_horizontal_m, cfg.sigma_horizontal_m, cfg.sigma_vertical_m])
    enu = true_enu + rng.normal(0.0, 1.0, true_enu.shape) * sigma
    if cfg.multipath_jump_m > 0:
        a, b = cfg.multipath_interval_s
        heading = rng.uniform(0.0, 2 * np.pi)  # direction of the reflected-path bias
        during = (times >= a) & (times < b)
        enu[during, :2] += cfg.multipath_jump_m * np.array([np.cos(heading), np.sin(heading)])
    status = np.where(rng.random(times.size) < cfg.dropout_probability, STATUS_NO_FIX, STATUS_FIX)
    cov = np.tile(np.diag(sigma ** 2), (times.size, 1, 1))
    lla = enu_to_lla(enu, np.asarray(cfg.origin_lla, float))
    return GnssFixes(np.asarray(times, float), lla, cov, status, true_enu)
