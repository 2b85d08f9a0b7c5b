"""GNSS receiver model: the antenna's true position (ENU about the configured geodetic origin,
exactly converted to WGS-84), white noise with the reported covariance, NO_FIX dropouts (status
-1) and an optional multipath jump (a horizontal offset held over an interval). The field profile
changes fix type, noise and multipath with the distance to structures."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrnc_eval.geodesy import enu_to_lla
from mrnc_eval.sim.config import FieldGnssConfig, GnssSimConfig
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
    status = with_outages(times, status, cfg.outages_s)
    cov = np.tile(np.diag(sigma ** 2), (times.size, 1, 1))
    lla = enu_to_lla(enu, np.asarray(cfg.origin_lla, float))
    return GnssFixes(np.asarray(times, float), lla, cov, status, true_enu)


STATUS_SBAS_FIX, STATUS_GBAS_FIX = 1, 2  # float / SBAS and RTK fixed (GBAS) in sensor_msgs/NavSatStatus


def with_outages(times: np.ndarray, status: np.ndarray, outages_s: tuple[tuple[float, float], ...]) -> np.ndarray:
    """NO_FIX inside each [start, end) interval (s since the log start)."""
    status = status.copy()
    for a, b in outages_s:
        status[(times >= a) & (times < b)] = STATUS_NO_FIX
    return status


def simulate_field_gnss(traj: BodyTrajectory, times: np.ndarray, base_to_antenna: np.ndarray, cfg: GnssSimConfig,
                        field: FieldGnssConfig, structures_xy: np.ndarray, rng: np.random.Generator) -> GnssFixes:
    """Fix type and noise from the antenna's horizontal distance to the nearest structure point
    (m): RTK fixed in the open, float within `float_within_m`, single point within
    `single_within_m`; multipath jumps (held horizontal offsets) start at `multipath_rate_hz`
    while within `float_within_m`. sim.gnss.mode other than profile: that fix type everywhere
    (float: multipath everywhere). NO_FIX dropouts as in the ideal model, and outages. `times`
    are the true measurement epochs; the clock model stamps them late."""
    p, r = traj.pose(times)
    true_enu = p + r.apply(base_to_antenna[:3, 3])
    near = _distance_to(structures_xy, true_enu[:, :2])
    status = np.where(near < field.single_within_m, STATUS_FIX,
                      np.where(near < field.float_within_m, STATUS_SBAS_FIX, STATUS_GBAS_FIX))
    forced = {"rtk": STATUS_GBAS_FIX, "float": STATUS_SBAS_FIX, "single": STATUS_FIX}.get(cfg.mode)
    if forced is not None:
        status = np.full(times.size, forced)
        near = np.where(status == STATUS_GBAS_FIX, np.inf, 0.0)  # multipath where the fix is not RTK
    sigma_h = np.select([status == STATUS_FIX, status == STATUS_SBAS_FIX],
                        [field.sigma_single_m, field.sigma_float_m], field.sigma_fixed_m)
    sigma = np.c_[sigma_h, sigma_h, 1.7 * sigma_h]  # vertical ~1.7x horizontal (satellite geometry)
    enu = true_enu + rng.normal(0.0, 1.0, true_enu.shape) * sigma
    enu[:, :2] += _multipath(times, near < field.float_within_m, field, rng)
    status = np.where(rng.random(times.size) < cfg.dropout_probability, STATUS_NO_FIX, status)
    status = with_outages(times, status, cfg.outages_s)
    cov = np.einsum("ni,ij->nij", sigma ** 2, np.eye(3))
    lla = enu_to_lla(enu, np.asarray(cfg.origin_lla, float))
    return GnssFixes(np.asarray(times, float), lla, cov, status, true_enu)


def _distance_to(points_xy: np.ndarray, xy: np.ndarray) -> np.ndarray:
    if len(points_xy) == 0:
        return np.full(len(xy), np.inf)
    from scipy.spatial import cKDTree

    return cKDTree(points_xy).query(xy)[0]


def _multipath(times: np.ndarray, exposed: np.ndarray, field: FieldGnssConfig, rng: np.random.Generator) -> np.ndarray:
    """(N, 2) m: each jump starts at an exposed epoch (Poisson, rate per s) and holds a random
    horizontal offset for a random duration."""
    out = np.zeros((times.size, 2))
    dt = np.diff(times, prepend=times[0] - (times[1] - times[0] if times.size > 1 else 0.2))
    starts = np.flatnonzero(exposed & (rng.random(times.size) < field.multipath_rate_hz * dt))
    for k in starts:
        size, heading = rng.uniform(*field.multipath_jump_m), rng.uniform(0.0, 2 * np.pi)
        during = (times >= times[k]) & (times < times[k] + rng.uniform(*field.multipath_duration_s))
        out[during] += size * np.array([np.cos(heading), np.sin(heading)])
    return out
