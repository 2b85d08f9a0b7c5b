"""Range-image projection (LIO-SAM imageProjection): keep points within the range limits and
outside the body crop box, row = ring (every downsample_rate-th), column from the cloud layout
or from the azimuth, first point per pixel wins, then flatten ring-major so each ring is a contiguous run."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrnc_eval.data import Sweep
from mrnc_eval.slam import _prep_kernels
from mrnc_eval.slam.config import FeatureConfig, SensorConfig


@dataclass(frozen=True, kw_only=True)
class RangeImage:
    """A sweep's points in range-image order, with ring and column."""

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
    keep, _ = _range_and_keep(points, -np.inf, np.inf, box)
    return keep


def _range_and_keep(points: np.ndarray, min_range: float, max_range: float,
                    box: tuple[float, ...] | None) -> tuple[np.ndarray, np.ndarray]:
    """One pass over the cloud (float32 or float64, read as float64): each point's range (m,
    float64) and whether it is kept (finite, within [min_range, max_range], outside box [x_min,
    y_min, z_min, x_max, y_max, z_max] unless None). numpy needed a float64 copy of the cloud and
    eight temporaries for the same."""
    pts = _real(points)
    keep, rng = np.empty(len(pts), bool), np.empty(len(pts))
    _prep_kernels.range_and_keep(pts, keep, rng, float(min_range), float(max_range),
                                 None if box is None else tuple(float(v) for v in box))
    return keep, rng


def project(sweep: Sweep, sensor: SensorConfig, features: FeatureConfig) -> RangeImage:
    box = features.body_crop_box_m
    keep, rng = _range_and_keep(sweep.points, features.min_range_m, features.max_range_m, box)
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
    return _gather(sweep, ring, column, rng, idx, rate)


def _kept_in_pixel_order(keep: np.ndarray, ring: np.ndarray, column: np.ndarray, width: int,
                         rate: int) -> tuple[np.ndarray, bool]:
    """Indices of the kept points on every rate-th ring, and whether their pixels (ring * width +
    column) strictly ascend (then they are the image as they come: one point per pixel, in order)."""
    idx = np.empty(keep.size, np.int64)
    m, ordered = _prep_kernels.kept_in_pixel_order(keep, ring, column, int(width), int(rate), idx)
    return idx[:m], ordered


def _gather(sweep: Sweep, ring: np.ndarray, column: np.ndarray, rng: np.ndarray, idx: np.ndarray,
            rate: int) -> RangeImage:
    """The image's arrays at idx in one pass: points and times as float64, ring // rate."""
    points, t = _real(sweep.points), _real(sweep.point_time if sweep.point_time is not None else np.zeros(0))
    n = idx.size
    out, ring_out, col_out, rng_out = np.empty((n, 3)), np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n)
    t_out = np.empty(n if t.size else 0)
    _prep_kernels.gather(points, ring, column, rng, t, idx, rate, out, ring_out, col_out, rng_out, t_out)
    return RangeImage(points=out, ring=ring_out, column=col_out, range_m=rng_out,
                      point_time=t_out if sweep.point_time is not None else None)


def _real(a: np.ndarray) -> np.ndarray:
    """`a` as the kernels read it: C-contiguous float32 or float64 (other dtypes as float64)."""
    return np.ascontiguousarray(a if a.dtype in (np.float32, np.float64) else a.astype(np.float64))
