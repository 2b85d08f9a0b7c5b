"""The IMU-LiDAR time offset from rotations neither the IMU nor the wheels pulled (issue 28).

The online poses are not the LiDAR's alone: the IMU-driven guess, the wheels' yaw hold and graph
#1's wheel and GNSS factors pull them towards the (mis-timed) IMU and wheels, so an offset read from
them reads 0.65-0.95 of a lag and carries the wheels' timing. After the run every mapped sweep that
is not a keyframe's is matched again, without any prior, from its final pose against one map of all
keyframes in their final poses. Their rotation increments are compared with the gyro over 0.35-0.85 s,
not between consecutive sweeps: over 0.2 s the re-matched poses still carry part of a lag (forest seed
2: 30 ms read as 22.8 ms; over 0.35-0.85 s 28.7 ms): their short-term errors move with the motion.
Still IMU-timed: the features' rotation deskew and the keyframe poses the map is built from (a lag
reads ~3 % short; docs/simulation.md)."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from mrnc_eval.geometry import rotation, se3
from mrnc_eval.slam.config import MatchingConfig
from mrnc_eval.slam.features import Features, voxel_downsample
from mrnc_eval.slam.imu import ImuTrack
from mrnc_eval.slam.scan_to_map import LocalMap, match
from mrnc_eval.slam.time_offset import SEARCH_S, OffsetEstimate, offset_from_overlapping

BASELINE_S = (0.35, 0.85)  # rotation increments between re-matched sweeps this far apart (s) are compared
JACKKNIFE_BLOCKS = 10  # contiguous stretches of the log left out in turn for the standard error
STRETCH_S = 2.0  # the sweeps kept for the re-match come in stretches of this much log time (s)
MIN_SPACING_S = 0.19  # a sweep closer than this to the last one kept is not kept (s): mapped every
# sweep at 10 Hz, every other one (LIO-SAM's 0.15 s rate keeps each): half the memory and CPU


@dataclass(kw_only=True)
class SweepStore:
    """The mapped sweeps' compact features kept for the re-match, at most `max_sweeps` of them: the
    log cut into STRETCH_S stretches, every `step`-th stretch kept; over the budget the step doubles
    and every other kept stretch goes (bounded memory, 42 kB per OS0-32 x 512 sweep, and CPU, with
    stretches long enough for the 0.35-0.85 s pairs and spread over the whole log). Each sweep keeps at
    most `max_points` edge and surface points, every k-th (a rotation is pinned by a few thousand
    points; an OS0-128 x 1024 sweep's ~12k surface points cost 4x the re-match for the same offset),
    and sweeps are kept MIN_SPACING_S apart."""

    max_sweeps: int
    max_points: int = 2000
    step: int = 1
    t0: float | None = None
    last: float | None = None  # stamp of the last sweep kept (s)
    feats: dict[int, Features] = field(default_factory=dict)  # by mapped-sweep index
    stamps: dict[int, float] = field(default_factory=dict)

    def kept(self, stamp: float) -> bool:
        return int((stamp - (self.t0 if self.t0 is not None else stamp)) // STRETCH_S) % self.step == 0

    def add(self, index: int, stamp: float, feats: Features) -> None:
        """Keep sweep `index` (its features already compact) when its stretch is kept; thin to the budget."""
        if self.t0 is None:
            self.t0 = stamp
        if not self.kept(stamp) or (self.last is not None and stamp - self.last < MIN_SPACING_S):
            return
        self.last = stamp
        self.feats[index] = Features(edges=_every_kth(feats.edges, self.max_points),
                                     surfs=_every_kth(feats.surfs, self.max_points))
        self.stamps[index] = stamp
        while len(self.feats) > self.max_sweeps:
            self.step *= 2
            gone = [i for i, t in self.stamps.items() if not self.kept(t)]
            for i in gone:
                del self.feats[i], self.stamps[i]


def _every_kth(points: np.ndarray, at_most: int) -> np.ndarray:
    """Every k-th row, k the smallest that leaves at most `at_most` rows (the rows unchanged below it);
    a copy, so the whole sweep's array is not held."""
    step = -(-len(points) // at_most)
    return points if step <= 1 else np.ascontiguousarray(points[::step])


@dataclass(frozen=True, kw_only=True)
class RunForOffset:
    """What the run leaves for the re-match: every mapped sweep's stamp (s) and final pose (4x4), the
    kept sweeps' compact features by index (sensor frame, deskewed as in the run; SweepStore), whether
    each sweep is a keyframe's own; every keyframe's final pose and features."""

    stamps: np.ndarray
    poses: np.ndarray
    feats: dict[int, Features]
    is_keyframe: np.ndarray
    kf_poses: np.ndarray
    kf_feats: list[Features]


def global_map(run: RunForOffset, cfg: MatchingConfig) -> LocalMap:
    """Every keyframe's features in its final pose, voxelised as the local map is."""
    edges = [se3.apply(p, f.edges) for p, f in zip(run.kf_poses, run.kf_feats, strict=True)]
    surfs = [se3.apply(p, f.surfs) for p, f in zip(run.kf_poses, run.kf_feats, strict=True)]
    return LocalMap.build(voxel_downsample(np.vstack(edges), cfg.corner_leaf_m),
                          voxel_downsample(np.vstack(surfs), cfg.surf_leaf_m))


def rematched_rotations(run: RunForOffset, cfg: MatchingConfig, keep: np.ndarray, workers: int = 1
                        ) -> tuple[np.ndarray, np.ndarray]:
    """(indices, (M, 3, 3) rotations) of the kept sweeps in `keep` (bool per sweep) that are not
    keyframes and match the whole map again without a degenerate direction (a keyframe's sweep would
    meet its own cloud and keep its pose). The sweeps are independent: `workers` threads match them
    (the kernels release the GIL), the same rotations in the same order whatever the number."""
    whole = global_map(run, cfg)
    todo = [j for j in (int(k) for k in np.flatnonzero(keep & ~run.is_keyframe)) if j in run.feats]

    def one(j: int) -> np.ndarray | None:
        f = run.feats[j]
        res = match(np.asarray(f.edges, np.float64), np.asarray(f.surfs, np.float64), whole, run.poses[j], cfg)
        return res.pose[:3, :3] if res.optimised and not res.degenerate else None

    if workers > 1 and len(todo) > 1:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            found = list(pool.map(one, todo))
    else:
        found = [one(j) for j in todo]
    idx = [j for j, r in zip(todo, found, strict=True) if r is not None]
    rots = [r for r in found if r is not None]
    return np.asarray(idx, np.int64), np.asarray(rots, np.float64).reshape(-1, 3, 3)


def baseline_rates(stamps: np.ndarray, rots: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pair of poses BASELINE_S apart: (t0, t1, mean angular velocity (rad/s, body axes)); stamps
    ascending. The candidates are found by search (the pairs grow with the sweeps, not their square)."""
    lo = np.searchsorted(stamps, stamps + BASELINE_S[0] - 1e-9)
    hi = np.searchsorted(stamps, stamps + BASELINE_S[1] + 1e-9, side="right")
    counts = np.maximum(hi - lo, 0)
    i = np.repeat(np.arange(stamps.size), counts)
    j = np.arange(i.size) - np.repeat(np.cumsum(counts) - counts, counts) + np.repeat(lo, counts)
    dt = stamps[j] - stamps[i]
    ok = (dt >= BASELINE_S[0]) & (dt <= BASELINE_S[1])
    i, j = i[ok], j[ok]
    rates = rotation.log(np.swapaxes(rots[i], 1, 2) @ rots[j]) / dt[ok][:, None]
    return stamps[i], stamps[j], np.asarray(rates, np.float64).reshape(-1, 3)


def rematch_time_offset(run: RunForOffset, track: ImuTrack, cfg: MatchingConfig,
                        measured: np.ndarray, workers: int = 1) -> OffsetEstimate | None:
    """The offset (s, positive: IMU stamps late) from the re-matched rotations against the gyro, with a
    jackknife standard error; `measured` marks the sweeps the run matched (scan-to-map ran, not
    degenerate). None with too few pairs (a throttled log's sweeps 1 s apart) or no rotation."""
    t = run.stamps
    if t.size < 2 or not run.kf_feats:
        return None
    keep = np.asarray(measured, bool) & (t - SEARCH_S >= track.stamps[0]) & (t + SEARCH_S <= track.stamps[-1])
    idx, rots = rematched_rotations(run, cfg, keep, workers)
    if idx.size < 2:
        return None
    t0, t1, rates = baseline_rates(t[idx], rots)
    return offset_from_overlapping(t0, t1, rates, track, blocks=JACKKNIFE_BLOCKS)
