"""Range-image projection (LIO-SAM imageProjection): keep points within the range limits and
outside the body crop box, row = ring (every downsample_rate-th), column from the cloud layout
or from the azimuth, first point per pixel wins, then flatten ring-major so each ring is a contiguous run."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from mrnc_eval.data import Sweep
from mrnc_eval.slam.config import FeatureConfig, SensorConfig


@dataclass(frozen=True, kw_only=True)
class RangeImage:
    points: np.ndarray  # (N, 3) float64, sensor frame, ring-major then column order
    ring: np.ndarray  # (N,) int64 row of the image
    column: np.ndarray  # (N,) int64
    range_m: np.ndarray  # (N,)
    point_time: np.ndarray | None  # (N,) s since the sweep stamp

    def __len__(self) -> int:
        return int(self.points.shape[0])


def azimuth_column(points: np.ndarray, horizon_scan: int) -> np.ndarray:
    """LIO-SAM's column: -round((atan2(x, y) - 90 deg) / (360 deg / H)) + H / 2, wrapped into [0, H)."""
    deg = np.degrees(np.arctan2(points[:, 0], points[:, 1]))
    col = -np.round((deg - 90.0) / (360.0 / horizon_scan)).astype(np.int64) + horizon_scan // 2
    return np.asarray(np.mod(col, horizon_scan), np.int64)


def elevation_ring(points: np.ndarray, sensor: SensorConfig) -> np.ndarray:
    """Ring from the elevation angle for clouds without a ring field (uniform beam spacing)."""
    lo, hi = sensor.vertical_fov_deg
    el = np.degrees(np.arctan2(points[:, 2], np.hypot(points[:, 0], points[:, 1])))
    ring = np.round((hi - el) / (hi - lo) * (sensor.n_scan - 1)).astype(np.int64)  # ring 0 = top beam (Ouster)
    return np.asarray(np.clip(ring, 0, sensor.n_scan - 1), np.int64)


def outside_box(points: np.ndarray, box: tuple[float, ...] | None) -> np.ndarray:
    """(N,) True for points outside the axis-aligned `box` [x_min, y_min, z_min, x_max, y_max,
    z_max] (m, cloud frame); all True when box is None."""
    if box is None:
        return np.ones(len(points), bool)
    keep, _ = _range_and_keep(np.ascontiguousarray(points), -np.inf, np.inf, np.asarray(box, np.float64), True)
    return keep


@njit(cache=True, nogil=True)
def _range_and_keep(points: np.ndarray, min_range: float, max_range: float, box: np.ndarray,
                    use_box: bool) -> tuple[np.ndarray, np.ndarray]:
    """One pass over the cloud: each point's range (m, float64) and whether it is kept (finite,
    within [min_range, max_range], outside box [x_min, y_min, z_min, x_max, y_max, z_max] when
    use_box). numpy needed a float64 copy of the cloud and eight temporaries for the same."""
    n = points.shape[0]
    keep = np.empty(n, np.bool_)
    rng = np.empty(n)
    for i in range(n):
        x, y, z = np.float64(points[i, 0]), np.float64(points[i, 1]), np.float64(points[i, 2])
        r = np.sqrt(x * x + y * y + z * z)
        rng[i] = r
        k = np.isfinite(r) and min_range <= r <= max_range
        if k and use_box:
            k = not (box[0] <= x <= box[3] and box[1] <= y <= box[4] and box[2] <= z <= box[5])
        keep[i] = k
    return keep, rng


def project(sweep: Sweep, sensor: SensorConfig, features: FeatureConfig) -> RangeImage:
    box = features.body_crop_box_m
    keep, rng = _range_and_keep(np.ascontiguousarray(sweep.points), features.min_range_m, features.max_range_m,
                                np.asarray(box if box is not None else np.zeros(6), np.float64), box is not None)
    if sweep.ring is not None:
        ring = sweep.ring.astype(np.int64)
    else:
        ring = elevation_ring(sweep.points.astype(np.float64), sensor)
    if sweep.column is not None:
        column = sweep.column.astype(np.int64)
        width = int(column.max(initial=0)) + 1
    else:
        column = azimuth_column(sweep.points.astype(np.float64), sensor.horizon_scan)
        width = sensor.horizon_scan
    rate = max(sensor.downsample_rate, 1)
    idx, ordered = _kept_in_pixel_order(keep, ring, column, width, rate)
    if not ordered:  # organised clouds arrive ring-major already; others are sorted here
        pixel = ring[idx] * width + column[idx]
        order = np.argsort(pixel, kind="stable")
        pixel, idx = pixel[order], idx[order]
        first = np.r_[True, pixel[1:] != pixel[:-1]]  # first point per pixel wins
        idx = idx[first]
    has_time = sweep.point_time is not None
    t_in = np.ascontiguousarray(sweep.point_time) if sweep.point_time is not None else np.zeros(0, np.float32)
    points, ring_out, col_out, rng_out, t = _gather(np.ascontiguousarray(sweep.points), ring, column, rng, t_in,
                                                    idx, rate)
    return RangeImage(points=points, ring=ring_out, column=col_out, range_m=rng_out, point_time=t if has_time else None)


@njit(cache=True, nogil=True)
def _kept_in_pixel_order(keep: np.ndarray, ring: np.ndarray, column: np.ndarray, width: int,
                         rate: int) -> tuple[np.ndarray, bool]:
    """Indices of the kept points on every rate-th ring, and whether their pixels (ring * width +
    column) strictly ascend (then they are the image as they come: one point per pixel, in order)."""
    idx = np.empty(keep.size, np.int64)
    m, last, ordered = 0, np.int64(-1), True
    for i in range(keep.size):
        if keep[i] and ring[i] % rate == 0:
            pixel = ring[i] * width + column[i]
            if m > 0 and pixel <= last:
                ordered = False
            last = pixel
            idx[m] = i
            m += 1
    return idx[:m], ordered


@njit(cache=True, nogil=True)
def _gather(points: np.ndarray, ring: np.ndarray, column: np.ndarray, rng: np.ndarray, point_time: np.ndarray,
            idx: np.ndarray, rate: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The image's arrays at idx in one pass: points and times as float64, ring // rate."""
    n = idx.size
    out = np.empty((n, 3))
    ring_out, col_out, rng_out = np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n)
    t = np.empty(n if point_time.size else 0)
    for j in range(n):
        i = idx[j]
        out[j, 0], out[j, 1], out[j, 2] = np.float64(points[i, 0]), np.float64(points[i, 1]), np.float64(points[i, 2])
        ring_out[j], col_out[j], rng_out[j] = ring[i] // rate, column[i], rng[i]
        if point_time.size:
            t[j] = np.float64(point_time[i])
    return out, ring_out, col_out, rng_out, t
