"""The IMU-LiDAR time offset from rotations the IMU and wheels did not touch (issue 28).

The online poses are not the LiDAR's alone: the IMU-driven guess, the wheels' yaw hold, the roll and
pitch blend and graph #1's wheel and GNSS factors all pull them towards the (mis-timed) IMU and the
wheels, so an offset read from them under-reads a lag (0.8-0.9 of it) and carries the wheels' timing.
After the run every mapped sweep that is not a keyframe is matched again, without any prior, from
its final pose against one map of all keyframes in their final poses: consecutive sweeps then meet
the same map, whose own errors are fixed in space, so their rotation increment is the LiDAR's."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrnc_eval.geometry import se3
from mrnc_eval.slam.config import MatchingConfig
from mrnc_eval.slam.features import Features, voxel_downsample
from mrnc_eval.slam.imu import ImuTrack
from mrnc_eval.slam.scan_to_map import LocalMap, match
from mrnc_eval.slam.time_offset import SEARCH_S, OffsetEstimate, lidar_angular_rates, offset_from_rates

MAX_GAP_S = 0.45  # consecutive re-matched sweeps further apart than this (s) are not paired: a keyframe
# sweep between two mapped sweeps 0.2 s apart is skipped, two in a row break the chain


@dataclass(frozen=True, kw_only=True)
class RunForOffset:
    """What the run leaves for the re-match: every mapped sweep's stamp (s), final pose (4x4), compact
    features (sensor frame, deskewed as in the run) and whether it is a keyframe's own sweep; every
    keyframe's final pose and features."""

    stamps: np.ndarray
    poses: np.ndarray
    feats: list[Features]
    is_keyframe: np.ndarray
    kf_poses: np.ndarray
    kf_feats: list[Features]


def global_map(run: RunForOffset, cfg: MatchingConfig) -> LocalMap:
    """Every keyframe's features in its final pose, voxelised as the local map is."""
    edges = [se3.apply(p, f.edges) for p, f in zip(run.kf_poses, run.kf_feats, strict=True)]
    surfs = [se3.apply(p, f.surfs) for p, f in zip(run.kf_poses, run.kf_feats, strict=True)]
    return LocalMap.build(voxel_downsample(np.vstack(edges), cfg.corner_leaf_m),
                          voxel_downsample(np.vstack(surfs), cfg.surf_leaf_m))


def rematched_rotations(run: RunForOffset, cfg: MatchingConfig, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(indices, (M, 3, 3) rotations) of the sweeps in `keep` (bool per sweep) that are not keyframes
    and match the whole map again without a degenerate direction (a keyframe's sweep would meet
    its own cloud and keep its pose)."""
    whole = global_map(run, cfg)
    idx, rots = [], []
    for j in np.flatnonzero(keep & ~run.is_keyframe):
        res = match(np.asarray(run.feats[j].edges, np.float64), np.asarray(run.feats[j].surfs, np.float64),
                    whole, run.poses[j], cfg)
        if res.optimised and not res.degenerate:
            idx.append(int(j))
            rots.append(res.pose[:3, :3])
    return np.asarray(idx, np.int64), np.asarray(rots, np.float64).reshape(-1, 3, 3)


def rematch_time_offset(run: RunForOffset, track: ImuTrack, cfg: MatchingConfig,
                        measured: np.ndarray) -> OffsetEstimate | None:
    """The offset (s, positive: IMU stamps late) from the re-matched rotations against the gyro, with
    its formal standard error (time_offset.offset_from_rates); `measured` marks the sweeps the run
    matched (scan-to-map ran, not degenerate). None when there are too few pairs or no rotation."""
    t = run.stamps
    keep = np.asarray(measured, bool) & (t - SEARCH_S >= track.stamps[0]) & (t + SEARCH_S <= track.stamps[-1])
    if run.stamps.size < 2 or not run.kf_feats:
        return None
    idx, rots = rematched_rotations(run, cfg, keep)
    if idx.size < 2:
        return None
    stamps = t[idx]
    pair = np.diff(stamps) <= MAX_GAP_S
    rates = lidar_angular_rates(stamps, rots)[pair]
    return offset_from_rates(stamps[:-1][pair], stamps[1:][pair], rates, track)
