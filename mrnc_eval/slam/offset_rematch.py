"""The IMU-LiDAR time offset from rotations neither the IMU nor the wheels pulled (issue 28).

The online poses are not the LiDAR's alone: the IMU-driven guess, the wheels' yaw hold and graph
#1's wheel and GNSS factors pull them towards the (mis-timed) IMU and wheels, so an offset read from
them reads 0.65-0.95 of a lag and carries the wheels' timing. After the run every kept mapped sweep is
matched again, without any prior, from its final pose against a map of keyframes in their final poses.
Their rotation increments are compared with the gyro over 0.35-0.85 s, not between consecutive sweeps:
over 0.2 s the re-matched poses still carry part of a lag (forest seed 2: 30 ms read as 22.8 ms; over
0.35-0.85 s 28.7 ms): their short-term errors move with the motion.

The keyframes' own poses lag the motion too (their yaw error follows the yaw rate, -2 ms on the forest
loop, and stays correlated for about 5 s), and a sweep matched against keyframes of the same moments
inherits part of it (the forest read -0.6 ms at no lag, the yard +0.9): each 2 s stretch of sweeps is
matched against the keyframes more than EXCLUDE_S away from it in time (their errors share nothing with
its motion), which also lets keyframes' own sweeps be matched. Still IMU-timed: the features'
rotation deskew (a second pass with the offset applied removes that; commands/slam.py)."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from mrnc_eval.geometry import rotation, se3
from mrnc_eval.slam.config import MatchingConfig
from mrnc_eval.slam.features import Features, voxel_downsample
from mrnc_eval.slam.imu import ImuTrack
from mrnc_eval.slam.scan_to_map import LocalMap, match
from mrnc_eval.slam.time_offset import SEARCH_S, OffsetEstimate, offset_from_overlapping

BASELINE_S = (0.35, 0.85)  # rotation increments between re-matched sweeps this far apart (s) are compared
EXCLUDE_S = 5.0  # a stretch is matched against keyframes at least this far from it in time (s): the online
# yaw errors' autocorrelation is 0.3-0.5 at 3 s, 0.3 at 5 s, 0.0-0.2 at 8 s (forest loop, tuning seeds 0-2)
MIN_MAP_KEYFRAMES = 3  # fewer such keyframes (a short log): the stretch meets every keyframe but its own
MAP_KEYFRAMES = 50  # at most this many in a stretch's map, the nearest to it: a map per stretch stays the size
# of the run's local map on an hour-long log (the 40 s field logs have 20-40 keyframes in all)
JACKKNIFE_BLOCKS = 10  # contiguous stretches of the log (equal shares of the information) left out in turn
# for the standard error
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
    kept sweeps' compact features by index (sensor frame, deskewed as in the run; SweepStore); every
    keyframe's stamp (s, its own sweep's), final pose and features."""

    stamps: np.ndarray
    poses: np.ndarray
    feats: dict[int, Features]
    kf_stamps: np.ndarray
    kf_poses: np.ndarray
    kf_feats: list[Features]


def keyframe_map(run: RunForOffset, cfg: MatchingConfig, keyframes: np.ndarray) -> LocalMap:
    """The given keyframes' features in their final poses, voxelised as the local map is."""
    edges = [se3.apply(run.kf_poses[k], run.kf_feats[k].edges) for k in keyframes]
    surfs = [se3.apply(run.kf_poses[k], run.kf_feats[k].surfs) for k in keyframes]
    return LocalMap.build(voxel_downsample(np.vstack(edges), cfg.corner_leaf_m),
                          voxel_downsample(np.vstack(surfs), cfg.surf_leaf_m))


def stretch_keyframes(run: RunForOffset, sweeps: list[int], map_radius_m: float) -> np.ndarray:
    """The keyframes a stretch of sweeps is matched against, ascending: more than EXCLUDE_S from the
    stretch in time and within map_radius_m of one of its sweeps, at most MAP_KEYFRAMES of them, the
    nearest; when fewer than MIN_MAP_KEYFRAMES are that far apart, the nearest within reach whenever they
    were recorded (the stretch's keyframe sweeps are then not matched: they would meet their own cloud)."""
    t0, t1 = run.stamps[sweeps[0]], run.stamps[sweeps[-1]]
    gap = np.maximum(t0 - run.kf_stamps, run.kf_stamps - t1)  # s from the stretch; negative inside it
    near = np.linalg.norm(run.kf_poses[:, None, :3, 3] - run.poses[sweeps][None, :, :3, 3], axis=2).min(axis=1)
    reach = near <= map_radius_m
    apart = np.flatnonzero(reach & (gap > EXCLUDE_S))
    chosen = apart if apart.size >= MIN_MAP_KEYFRAMES else np.flatnonzero(reach)
    return np.sort(chosen[np.argsort(near[chosen], kind="stable")[:MAP_KEYFRAMES]])


def rematched_rotations(run: RunForOffset, cfg: MatchingConfig, keep: np.ndarray, workers: int = 1
                        ) -> tuple[np.ndarray, np.ndarray]:
    """(indices, (M, 3, 3) rotations) of the kept sweeps in `keep` (bool per sweep) that match their
    stretch's keyframes again (`stretch_keyframes`; a sweep never meets its own keyframe's cloud, where it
    would keep its pose) without a degenerate direction. One stretch's map at a time (bounded memory);
    its sweeps are independent: `workers` threads match them (the kernels release the GIL), the same
    rotations in the same order whatever the number."""
    kf_of_sweep = {int(j): k for k, j in enumerate(np.searchsorted(run.stamps, run.kf_stamps))
                   if j < run.stamps.size and run.stamps[j] == run.kf_stamps[k]}
    stretches: dict[int, list[int]] = {}
    for j in (int(k) for k in np.flatnonzero(keep)):
        if j in run.feats:
            stretches.setdefault(int((run.stamps[j] - run.stamps[0]) // STRETCH_S), []).append(j)

    def one(whole: LocalMap, j: int) -> np.ndarray | None:
        f = run.feats[j]
        res = match(np.asarray(f.edges, np.float64), np.asarray(f.surfs, np.float64), whole, run.poses[j], cfg)
        return res.pose[:3, :3] if res.optimised and not res.degenerate else None

    idx: list[int] = []
    rots: list[np.ndarray] = []
    with ThreadPoolExecutor(max_workers=workers) as pool:
        for sweeps in stretches.values():
            keyframes = stretch_keyframes(run, sweeps, cfg.map_radius_m)
            if {kf_of_sweep.get(j) for j in sweeps} & set(keyframes.tolist()):  # the fallback: own keyframes in
                sweeps = [j for j in sweeps if j not in kf_of_sweep]
            if not keyframes.size or not sweeps:
                continue
            whole = keyframe_map(run, cfg, keyframes)
            found = list(pool.map(partial(one, whole), sweeps)) if workers > 1 else [one(whole, j) for j in sweeps]
            idx += [j for j, r in zip(sweeps, found, strict=True) if r is not None]
            rots += [r for r in found if r is not None]
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
