"""Warm the per-sweep loop before it is timed: run matching and the loop-closure ICP once on a small
synthetic sweep, so a first-use cost (the ICP's pykdtree OpenMP start-up; once numba's compilation
of matching, 0.3-4 s, which made a stage's mean exceed its 95th percentile) is paid here and
reported on its own instead of landing in one sweep's stage time.

Since issue 30 every per-sweep kernel is C (slam/_prep_kernels.c, slam/_match_kernels.c): nothing is
compiled at run time and the warm-up takes a few ms (matching 2.0-2.5 ms, loop 1.8-3.0 ms on the room
sweep, first call and second alike). It stays as the guard that keeps such a cost out of the
per-sweep statistics. The range image, deskew and features run here only to give matching its input."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from mrnc_eval.data import Sweep
from mrnc_eval.geometry import se3
from mrnc_eval.slam.config import SlamConfig
from mrnc_eval.slam.deskew import deskew
from mrnc_eval.slam.features import extract_features, voxel_downsample
from mrnc_eval.slam.graph import register_loop
from mrnc_eval.slam.range_image import project
from mrnc_eval.slam.scan_to_map import LocalMap, match

ROOM_HALF_M = np.array([8.0, 6.0])  # x, y half-sizes of the synthetic room's walls, m
FLOOR_Z_M, CEILING_Z_M = -2.5, 3.0  # below / above the sensor, m
RINGS, COLUMNS = 16, 360  # a coarse sensor: enough edges (the room's corners) and planes for matching
WARMUP_STAGES = ("matching", "loop")


def room_sweep(stamp: float = 0.0, rings: int = RINGS, columns: int = COLUMNS) -> Sweep:
    """A sweep from the centre of a closed box room (ray-cast analytically), organised as `rings`
    x `columns` with ring, column and per-point time (0.1 s per turn), in the reader's dtypes."""
    elevation = np.radians(np.linspace(40.0, -40.0, rings))[:, None]
    azimuth = np.linspace(0.0, 2 * np.pi, columns, endpoint=False)[None, :]
    d = np.stack(np.broadcast_arrays(np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth),
                                     np.sin(elevation)), axis=-1).reshape(-1, 3)
    with np.errstate(divide="ignore"):
        hits = [np.where(d[:, a] != 0, np.abs(ROOM_HALF_M[a] / d[:, a]), np.inf) for a in (0, 1)]
        hits.append(np.where(d[:, 2] > 0, CEILING_Z_M / d[:, 2], np.where(d[:, 2] < 0, FLOOR_Z_M / d[:, 2], np.inf)))
    points = d * np.min(hits, axis=0)[:, None]
    column = np.tile(np.arange(columns, dtype=np.uint32), rings)
    ring = np.repeat(np.arange(rings, dtype=np.uint16), columns)
    return Sweep(stamp, points.astype(np.float32), (column * (0.1 / columns)).astype(np.float32), ring, column,
                 height=rings, width=columns)


def warm_up(cfg: SlamConfig) -> dict[str, float]:
    """Run scan-to-map matching and the loop-closure ICP once on `room_sweep`'s features; returns
    each stage's wall time (ms): compilation or cache loading, first-use set-up."""
    sweep = room_sweep()
    image = project(sweep, cfg.sensor, cfg.features)
    assert image.point_time is not None  # room_sweep has per-point time
    feats = extract_features(image, deskew(image.points, image.point_time, sweep.stamp, None, np.zeros(3)),
                             cfg.features)
    ms: dict[str, float] = {}
    t = time.perf_counter()

    def lap(stage: str) -> None:
        nonlocal t
        now = time.perf_counter()
        ms[stage] = (now - t) * 1e3
        t = now

    m = cfg.matching
    if len(feats.surfs) >= 5:  # a configuration that crops the room away leaves the compilation to the loop
        local_map = LocalMap.build(voxel_downsample(feats.edges, m.corner_leaf_m),
                                   voxel_downsample(feats.surfs, m.surf_leaf_m))
        # a guess a few cm off, so the Gauss-Newton loop iterates; minimums lowered for the small room
        # (the kernels compile the same whatever the counts)
        any_count = replace(m, min_edges=1, min_surfs=1, min_correspondences=1)
        match(feats.edges, feats.surfs, local_map, se3.make(np.eye(3), np.array([0.05, -0.03, 0.02])), any_count)
    lap("matching")
    cloud = voxel_downsample(np.r_[feats.edges, feats.surfs], cfg.loop.leaf_m)
    if cfg.loop.enabled and len(cloud) >= 5:
        register_loop(cloud, cloud, np.eye(4), cfg.loop)
    lap("loop")
    return ms

