"""WGS-84 geodetic <-> local ENU (exact, via ECEF). Angles in degrees, heights in metres."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

A = 6378137.0  # WGS-84 semi-major axis, m
F = 1.0 / 298.257223563  # flattening
E2 = F * (2.0 - F)  # first eccentricity squared


def lla_to_ecef(lla: NDArray[np.float64]) -> NDArray[np.float64]:
    lat, lon, h = np.radians(lla[..., 0]), np.radians(lla[..., 1]), lla[..., 2]
    n = A / np.sqrt(1.0 - E2 * np.sin(lat) ** 2)
    return np.stack(
        [(n + h) * np.cos(lat) * np.cos(lon), (n + h) * np.cos(lat) * np.sin(lon), (n * (1 - E2) + h) * np.sin(lat)],
        axis=-1,
    )


def _ecef_to_enu_rotation(origin_lla: NDArray[np.float64]) -> NDArray[np.float64]:
    lat, lon = np.radians(origin_lla[0]), np.radians(origin_lla[1])
    sl, cl, sp, cp = np.sin(lon), np.cos(lon), np.sin(lat), np.cos(lat)
    return np.array([[-sl, cl, 0.0], [-sp * cl, -sp * sl, cp], [cp * cl, cp * sl, sp]])


def lla_to_enu(lla: NDArray[np.float64], origin_lla: NDArray[np.float64]) -> NDArray[np.float64]:
    """East/north/up (m) of each fix relative to the origin."""
    rot = _ecef_to_enu_rotation(origin_lla)
    return (lla_to_ecef(lla) - lla_to_ecef(origin_lla)) @ rot.T


def enu_to_lla(enu: NDArray[np.float64], origin_lla: NDArray[np.float64]) -> NDArray[np.float64]:
    """Inverse of `lla_to_enu` (Bowring's iteration, converged to < 1e-9 m)."""
    rot = _ecef_to_enu_rotation(origin_lla)
    ecef = np.asarray(enu) @ rot + lla_to_ecef(origin_lla)
    x, y, z = ecef[..., 0], ecef[..., 1], ecef[..., 2]
    lon = np.arctan2(y, x)
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1 - E2))
    for _ in range(8):
        n = A / np.sqrt(1 - E2 * np.sin(lat) ** 2)
        h = p / np.cos(lat) - n
        lat = np.arctan2(z, p * (1 - E2 * n / (n + h)))
    n = A / np.sqrt(1 - E2 * np.sin(lat) ** 2)
    h = p / np.cos(lat) - n
    return np.stack([np.degrees(lat), np.degrees(lon), h], axis=-1)


def enu_covariance(cov_enu_diag_or_full: NDArray[np.float64]) -> NDArray[np.float64]:
    """NavSatFix position_covariance is already ENU (row-major 3x3, m^2)."""
    return np.asarray(cov_enu_diag_or_full, dtype=float).reshape(-1, 3, 3)
