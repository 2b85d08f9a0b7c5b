"""What the SLAM replay hands back: events raised while it runs and the finished output.
Shared by replay.py and the modules it drives (gnss.py), so neither imports the other."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mrnc_eval.slam.map_quality import MapQuality

# read: waiting for the sweep iterator (decoding, or only the wait when it runs ahead in another thread);
# projection: range image and feature labels (slam/sweep_prep.py), in the thread that prepared the sweep
STAGES = ("read", "projection", "deskew", "features", "matching", "graph", "loop")


@dataclass(kw_only=True)
class SlamEvent:
    """Something that happened during the replay, at a log time."""

    t: float  # log time, s
    kind: str  # "degeneracy", "loop_closure", "loop_rejected", "warning", "gps", "imu_time_offset"
    message: str
    data: dict[str, Any] = field(default_factory=dict)


@dataclass(kw_only=True)
class SlamOutput:
    """Everything the replay returns: poses, keyframes, map, events, timings."""

    stamps: np.ndarray  # processed sweeps, s
    poses: np.ndarray  # (N, 4, 4) LiDAR poses in the map frame, loop-corrected through their keyframe
    kf_stamps: np.ndarray
    kf_poses: np.ndarray
    map_points: np.ndarray
    timing_ms: dict[str, list[float]]
    events: list[SlamEvent]
    warnings: list[str]
    n_sweeps: int
    wall_s: float
    imu_bias: np.ndarray | None = None  # final [acc (3), gyro (3)] bias estimate of graph #2, LiDAR axes
    degenerate: np.ndarray | None = None  # (N,) bool per processed sweep
    online_poses: np.ndarray | None = None  # (N, 4, 4) each sweep's pose as estimated when it was processed
    imu_time_offset_s: float | None = None  # estimated IMU clock lag after slam.imu.time_offset_s, s
    map_quality: MapQuality | None = None
    deskew: bool = True  # False when the method ran without deskew (kiss-icp on throttled logs)
    # one-off cost per stage before the timed loop (first calls), ms
    warmup_ms: dict[str, float] = field(default_factory=dict)
    empty_sweeps: int = 0  # sweeps with no valid point (empty, all zero or non-finite): not mapped, counted
    imu_noise: dict[str, Any] | None = None  # the IMU's noise and biases from stationary stretches (imu_noise.py)
    imu_time_offset_sigma_s: float | None = None  # its standard error (jackknife with the re-match), s
    imu_time_offset_cpu_ms: float = 0.0  # CPU time of the offset's re-match after the run (0: not run), ms
    # per stage and sweep, CPU time of the thread that ran it (projection: the preparing thread), ms;
    # the KD-tree's OpenMP helpers are not in it (slam.threads = 1 holds them to the calling thread)
    cpu_ms: dict[str, list[float]] = field(default_factory=dict)
    wheel_health: dict[str, Any] | None = None  # slam/wheel_health.py: online wheel calibration and verdict
