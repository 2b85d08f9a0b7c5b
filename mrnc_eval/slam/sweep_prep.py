"""What the SLAM computes from a sweep alone, before it knows any pose: the range image and the
feature labels (smoothness from ranges, LIO-SAM's code) and each pixel's vertical neighbours (the
ground test's pairs). Nothing here depends on the replay's state, so it can run ahead of the
mapping loop in another thread (the reader's: commands/slam.py) and give the same arrays as
when it runs in line; the C kernels it calls (slam/_prep_kernels.c) release the GIL, so it overlaps with the
matching of the sweep before on the other core."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from mrnc_eval.data import Sweep
from mrnc_eval.slam.config import SlamConfig
from mrnc_eval.slam.features import feature_labels, vertical_neighbours
from mrnc_eval.slam.range_image import RangeImage, project


@dataclass(frozen=True, kw_only=True)
class PreparedSweep:
    """A sweep with what needs no pose done (in the reader thread)."""

    stamp: float  # the sweep's, s
    n_points: int  # the decoded sweep's points (0: an empty sweep, counted and skipped)
    image: RangeImage  # the sweep's points in range-image order (the decoded arrays themselves are not kept)
    labels: np.ndarray | None  # feature_labels; None: computed after deskew (smoothness "paper" reads points)
    vertical: np.ndarray | None  # vertical_neighbours; None: the ground test is off
    ms: float  # wall time of the preparation, ms, in the thread that ran it
    cpu_ms: float  # that thread's CPU time for it, ms


def prepare_sweep(sweep: Sweep, cfg: SlamConfig) -> PreparedSweep:
    """Range image, feature labels and vertical neighbours of one sweep (sensor frame, not deskewed)."""
    t0, c0 = time.perf_counter(), time.thread_time()
    image = project(sweep, cfg.sensor, cfg.features)
    labels = vertical = None
    if len(image) >= 12:
        if cfg.features.smoothness == "range":
            labels = feature_labels(image, None, cfg.features)
        if cfg.features.ground_max_angle_deg > 0:
            vertical = vertical_neighbours(image)
    return PreparedSweep(stamp=sweep.stamp, n_points=len(sweep), image=image, labels=labels, vertical=vertical,
                         ms=(time.perf_counter() - t0) * 1e3, cpu_ms=(time.thread_time() - c0) * 1e3)
