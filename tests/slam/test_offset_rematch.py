"""The IMU-LiDAR offset from rotation increments over 0.35-0.85 s (slam/offset_rematch.py): the fit on
overlapping intervals and its jackknife standard error. The re-match itself runs in the replay
(tests/slam/test_slam_time_offset_slow.py and _refine_slow.py hold it on simulated logs)."""

from __future__ import annotations

import numpy as np
import pytest


def _rocking(t: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (rad) of a machine rocking on rough ground while turning slowly."""
    return np.c_[0.05 * np.sin(2 * np.pi * 0.7 * t), 0.04 * np.sin(2 * np.pi * 1.1 * t + 1.0), 0.1 * t]


def _case(lag_s: float, seed: int) -> tuple[np.ndarray, np.ndarray, object]:
    """Gyro of the rocking at 100 Hz stamped `lag_s` late (with a constant bias); LiDAR rotations at
    5 Hz for 40 s with 0.05 deg noise per axis."""
    from scipy.spatial.transform import Rotation

    from mrnc_eval.data import ImuSeries
    from mrnc_eval.slam.imu import imu_track

    t_imu = np.arange(0.0, 42.0, 0.01)
    h = 1e-4
    rate = (Rotation.from_euler("xyz", _rocking(t_imu - h)).inv()
            * Rotation.from_euler("xyz", _rocking(t_imu + h))).as_rotvec() / (2 * h)
    imu = ImuSeries(t_imu + lag_s, np.tile([0.0, 0.0, 9.81], (t_imu.size, 1)), rate + [0.002, -0.001, 0.0005])
    t_lidar = np.arange(1.0, 41.0, 0.2)
    noise = Rotation.from_rotvec(np.random.default_rng(seed).normal(0.0, np.radians(0.05), (t_lidar.size, 3)))
    return t_lidar, (Rotation.from_euler("xyz", _rocking(t_lidar)) * noise).as_matrix(), imu_track(imu, np.eye(3))


@pytest.mark.parametrize("lag_s", [0.0, 0.008, 0.030])
def test_offset_from_increments_over_a_baseline_recovers_a_lag_with_an_honest_error(lag_s: float) -> None:
    """Every pair 0.35-0.85 s apart (each pose in 6 pairs): within 1 ms of the lag (errors measured
    0.04-0.30 ms) and within 4 jackknife standard errors; over 8 noise draws the rms of error / sigma
    is 0.66 (here the noise is independent per pose and the formal error, which takes the pairs as
    independent, is as good: rms 1.08)."""
    from mrnc_eval.slam.offset_rematch import baseline_rates
    from mrnc_eval.slam.time_offset import offset_from_overlapping

    z = []
    for seed in range(8):
        t, rots, track = _case(lag_s, seed)
        t0, t1, rates = baseline_rates(t, rots)
        assert 2.5 < t0.size / t.size < 3.5  # 0.4, 0.6 and 0.8 s
        est = offset_from_overlapping(t0, t1, rates, track)
        assert est is not None
        assert abs(est.offset_s - lag_s) < 1e-3
        assert abs(est.offset_s - lag_s) < 4 * est.sigma_s
        z.append((est.offset_s - lag_s) / est.sigma_s)
    assert 0.4 < float(np.sqrt(np.mean(np.square(z)))) < 2.0


def _still_after(drive_s: float, t: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (rad): rocking and a slow swing that stop smoothly at `drive_s` (the yaw swing at
    a turning point, the rocking faded over its last 5 s), then standing still."""
    x = np.clip((t - (drive_s - 5.0)) / 5.0, 0.0, 1.0)
    fade = 1.0 - x ** 3 * (10.0 - 15.0 * x + 6.0 * x * x)
    return np.c_[0.05 * np.sin(2 * np.pi * 0.7 * t) * fade, 0.04 * np.sin(2 * np.pi * 1.1 * t + 1.0) * fade,
                 0.3 * np.sin(2 * np.pi * 0.1 * np.minimum(t, drive_s))]


def _mostly_still_errors(seeds: range) -> tuple[np.ndarray, np.ndarray]:
    """(errors, sigmas) in s of the offset on 100 s logs that drive for the first 22.5 s: gyro at 100 Hz
    8 ms late with a bias and 2.6e-3 rad/s of white noise, LiDAR rotations at 5 Hz with 0.4 mrad per axis."""
    from scipy.spatial.transform import Rotation

    from mrnc_eval.data import ImuSeries
    from mrnc_eval.slam.imu import imu_track
    from mrnc_eval.slam.offset_rematch import baseline_rates
    from mrnc_eval.slam.time_offset import offset_from_overlapping

    def attitude(t: np.ndarray) -> Rotation:
        return Rotation.from_euler("xyz", _still_after(22.5, t))

    errors, sigmas = [], []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        t_imu, h = np.arange(0.0, 102.0, 0.01), 1e-4
        rate = (attitude(t_imu - h).inv() * attitude(t_imu + h)).as_rotvec() / (2 * h)
        rate += rng.normal(0.0, 2.6e-3, rate.shape) + [0.002, -0.001, 0.0005]
        track = imu_track(ImuSeries(t_imu + 0.008, np.tile([0.0, 0.0, 9.81], (t_imu.size, 1)), rate), np.eye(3))
        t = np.arange(1.0, 100.0, 0.2)
        rots = (attitude(t) * Rotation.from_rotvec(rng.normal(0.0, 4e-4, (t.size, 3)))).as_matrix()
        est = offset_from_overlapping(*baseline_rates(t, rots), track)
        assert est is not None
        errors.append(est.offset_s - 0.008)
        sigmas.append(est.sigma_s)
    return np.array(errors), np.array(sigmas)


def test_the_jackknife_error_holds_on_a_log_that_mostly_stands_still(monkeypatch: pytest.MonkeyPatch) -> None:
    """The jackknife leaves out blocks of equal information, not of equal time: on logs that drive for
    22.5 s of 100 s, over 12 noise draws, error / sigma rms within 0.5-2 (measured 0.78) and every sigma at
    least half the errors' rms (smallest 1.0x, 0.11 ms). Negative control: blocks of equal time (the rule
    before) put seven of ten blocks in the still part, whose replicates equal the estimate: sigmas as
    small as 0.29x the errors' rms (0.03 ms; error / sigma rms 1.27 here, 4.97 over 30 draws)."""
    from mrnc_eval.slam import time_offset

    def sound(errors: np.ndarray, sigmas: np.ndarray) -> bool:
        rms = float(np.sqrt(np.mean(errors ** 2)))
        return 0.5 < float(np.sqrt(np.mean((errors / sigmas) ** 2))) < 2.0 and float(sigmas.min()) > 0.5 * rms

    assert sound(*_mostly_still_errors(range(12)))

    def equal_time(t0: np.ndarray, t1: np.ndarray, mismatch: np.ndarray, t_imu: np.ndarray, integral: np.ndarray,
                   blocks: int) -> np.ndarray:
        return np.minimum(((t0 - t0.min()) / np.ptp(t0) * blocks).astype(np.int64), blocks - 1)

    monkeypatch.setattr(time_offset, "_information_blocks", equal_time)
    assert not sound(*_mostly_still_errors(range(12)))


def test_baseline_pairs_need_sweeps_closer_than_the_baseline() -> None:
    """A throttled log (sweeps 1 s apart) has no pair 0.35-0.85 s apart: no estimate, as the online
    estimator refuses 1 s rotation increments."""
    from mrnc_eval.slam.offset_rematch import baseline_rates
    from mrnc_eval.slam.time_offset import offset_from_overlapping

    t, rots, track = _case(0.008, 0)
    t0, t1, rates = baseline_rates(t[::5], rots[::5])
    assert t0.size == 0
    assert offset_from_overlapping(t0, t1, rates, track) is None


def test_sweeps_kept_for_the_rematch_stay_within_the_budget_in_stretches_over_the_whole_log() -> None:
    """1000 mapped sweeps 0.2 s apart (200 s) with a budget of 100: at most 100 kept, in whole 2 s
    stretches (10 sweeps each, so the 0.35-0.85 s pairs exist), from the first and the last quarter of
    the log alike; a budget above the sweeps keeps every one (the 40 s logs' case)."""
    from mrnc_eval.slam.features import Features
    from mrnc_eval.slam.offset_rematch import SweepStore

    feats = Features(edges=np.zeros((1, 3), np.float32), surfs=np.zeros((1, 3), np.float32))
    small, large = SweepStore(max_sweeps=100), SweepStore(max_sweeps=2000)
    stamps = 100.0 + 0.2 * np.arange(1000)
    for i, t in enumerate(stamps):
        small.add(i, float(t), feats)
        large.add(i, float(t), feats)
    kept = np.array(sorted(small.feats))
    assert 50 <= kept.size <= 100
    assert len(large.feats) == 1000
    runs = np.split(kept, np.flatnonzero(np.diff(kept) > 1) + 1)
    assert all(r.size == 10 for r in runs)
    assert kept.min() < 250
    assert kept.max() >= 750


def test_sweeps_kept_for_the_rematch_hold_at_most_max_points_spread_over_the_sweep() -> None:
    """An OS0-128-sized sweep (11,600 surface points) is kept as every 3rd point (3,867 <= 4,000), from
    its first to its last row, in its own array (not a view holding the whole sweep); a sweep under the
    cap (an OS0-32 x 512 one) is kept whole, the same array."""
    from mrnc_eval.slam.features import Features
    from mrnc_eval.slam.offset_rematch import SweepStore

    big = Features(edges=np.arange(1400 * 3, dtype=np.float32).reshape(-1, 3),
                   surfs=np.arange(11_600 * 3, dtype=np.float32).reshape(-1, 3))
    small = Features(edges=np.zeros((80, 3), np.float32), surfs=np.zeros((2300, 3), np.float32))
    store = SweepStore(max_sweeps=10, max_points=4000)
    store.add(0, 0.0, big)
    store.add(1, 0.2, small)
    kept = store.feats[0]
    assert kept.surfs.shape == (3867, 3)
    np.testing.assert_array_equal(kept.surfs, big.surfs[::3])
    assert kept.surfs.base is None or kept.surfs.base is not big.surfs
    assert kept.edges is big.edges  # 1,400 edges: under the cap
    assert store.feats[1].surfs is small.surfs


def test_sweeps_kept_for_the_rematch_are_at_least_min_spacing_apart() -> None:
    """Mapped every sweep at 10 Hz: every other sweep kept (0.2 s apart); at LIO-SAM's 5 Hz mapping
    rate every sweep is kept."""
    from mrnc_eval.slam.features import Features
    from mrnc_eval.slam.offset_rematch import MIN_SPACING_S, SweepStore

    feats = Features(edges=np.zeros((1, 3), np.float32), surfs=np.zeros((1, 3), np.float32))
    every, fifth = SweepStore(max_sweeps=1000), SweepStore(max_sweeps=1000)
    for i in range(100):
        every.add(i, 0.1 * i, feats)
        if i % 2 == 0:
            fifth.add(i, 0.1 * i, feats)
    assert sorted(every.feats) == list(range(0, 100, 2))
    assert sorted(fifth.feats) == list(range(0, 100, 2))
    assert 0.1 < MIN_SPACING_S < 0.2


def test_baseline_pairs_are_every_pair_035_to_085_s_apart_in_order() -> None:
    """The pairs found by search are the brute-force ones (all i < j with 0.35 <= dt <= 0.85 s, in
    (i, j) order), boundaries included, on uneven stamps; negative control: a brute force over
    0.3-0.9 s finds more."""
    from mrnc_eval.slam.offset_rematch import baseline_rates

    rng = np.random.default_rng(3)
    t = np.sort(np.r_[0.0, 0.35, 0.85, rng.uniform(1.0, 30.0, 250)])
    rots = np.repeat(np.eye(3)[None], t.size, axis=0)
    i, j = np.triu_indices(t.size, 1)
    dt = t[j] - t[i]
    ok = (dt >= 0.35) & (dt <= 0.85)
    t0, t1, rates = baseline_rates(t, rots)
    np.testing.assert_array_equal(t0, t[i[ok]])
    np.testing.assert_array_equal(t1, t[j[ok]])
    assert rates.shape == (ok.sum(), 3)
    pairs = set(zip(t0, t1, strict=True))
    assert (0.0, 0.35) in pairs
    assert (0.0, 0.85) in pairs
    assert ((dt >= 0.3) & (dt <= 0.9)).sum() > ok.sum()


def _room_run(kf_yaw_error: float) -> tuple[object, np.ndarray]:
    """A 20 s drive across the synthetic hall (tests/slam/test_slam_modules.py), sweeps 0.25 s apart from
    their true poses, a keyframe every 1 s; the keyframes of 8-12 s stored with `kf_yaw_error` (rad) of
    yaw, as online keyframes whose yaw lags a turn. Returns the run and the sweeps' true yaws."""
    from scipy.spatial.transform import Rotation

    from mrnc_eval.geometry import se3
    from mrnc_eval.slam.offset_rematch import RunForOffset
    from tests.slam.test_slam_modules import _features, _room, _scan

    scene = _room()
    stamps = np.arange(0.0, 20.0, 0.25)
    yaw = 0.2 * np.sin(2 * np.pi * stamps / 7.0)
    poses = np.array([se3.make(Rotation.from_euler("z", a).as_matrix(), np.array([-8.0 + 0.8 * t, 0.5, 1.0]))
                      for t, a in zip(stamps, yaw, strict=True)])
    feats = {}
    for i, p in enumerate(poses):
        f = _features(_scan(scene, p, cols=512))
        feats[i] = type(f)(edges=f.edges.astype(np.float32), surfs=f.surfs.astype(np.float32))
    kf = np.arange(0, stamps.size, 4)
    kf_poses = poses[kf].copy()
    lagging = (stamps[kf] >= 8.0) & (stamps[kf] <= 12.0)
    kf_poses[lagging, :3, :3] = Rotation.from_euler("z", kf_yaw_error).as_matrix() @ kf_poses[lagging, :3, :3]
    run = RunForOffset(stamps=stamps, poses=poses, feats=feats, kf_stamps=stamps[kf], kf_poses=kf_poses,
                       kf_feats=[feats[int(k)] for k in kf])
    return run, yaw


def test_a_stretch_is_rematched_against_keyframes_far_from_it_in_time_not_the_lagging_ones_of_its_moment(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Keyframes of 8-12 s carry 0.01 rad of yaw error (the online poses' lag through a turn): the sweeps
    of those seconds re-matched against keyframes more than EXCLUDE_S away keep their true yaw (within 1
    mrad), keyframe sweeps included; negative control: against every keyframe (the exclusion off) they
    inherit part of the error."""
    from mrnc_eval.geometry import rotation
    from mrnc_eval.slam import offset_rematch
    from mrnc_eval.slam.config import MatchingConfig

    run, yaw = _room_run(0.01)
    keep = np.ones(run.stamps.size, bool)

    def yaw_errors() -> tuple[np.ndarray, np.ndarray]:
        idx, rots = offset_rematch.rematched_rotations(run, MatchingConfig(), keep)
        inside = (run.stamps[idx] >= 8.0) & (run.stamps[idx] < 12.0)
        return idx[inside], rotation.rpy(rots[inside])[:, 2] - yaw[idx[inside]]

    idx, err = yaw_errors()
    assert idx.size >= 14  # of 16 sweeps
    assert np.isin(idx, [32, 36, 40, 44]).sum() >= 3  # the keyframes' own sweeps
    assert np.abs(err).max() < 1e-3
    monkeypatch.setattr(offset_rematch, "EXCLUDE_S", -1e9)  # every keyframe but a sweep's own
    _, pulled = yaw_errors()
    assert np.median(pulled) > 2e-3


def test_the_keyframes_of_a_stretch_are_those_far_in_time_and_within_the_map_radius(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """EXCLUDE_S apart in time and within map_radius_m of a sweep of the stretch, at most MAP_KEYFRAMES,
    the nearest; too few such (a short log): every keyframe within reach."""
    from mrnc_eval.slam import offset_rematch
    from mrnc_eval.slam.features import Features
    from mrnc_eval.slam.offset_rematch import EXCLUDE_S, RunForOffset, stretch_keyframes

    stamps = np.arange(0.0, 40.0, 0.5)
    poses = np.repeat(np.eye(4)[None], stamps.size, axis=0)
    poses[:, 0, 3] = 2.0 * stamps  # 2 m/s along x
    kf = np.arange(0, stamps.size, 2)  # a keyframe a second
    empty = Features(edges=np.zeros((0, 3)), surfs=np.zeros((0, 3)))
    run = RunForOffset(stamps=stamps, poses=poses, feats={}, kf_stamps=stamps[kf], kf_poses=poses[kf],
                       kf_feats=[empty] * kf.size)
    chosen = stretch_keyframes(run, [40, 41, 42, 43], map_radius_m=30.0)  # 20-21.5 s, x 40-43 m
    t = run.kf_stamps[chosen]
    assert chosen.size > 0
    assert np.all((t < 20.0 - EXCLUDE_S) | (t > 21.5 + EXCLUDE_S))
    assert np.all(np.abs(run.kf_poses[chosen, 0, 3] - 41.5) <= 31.5)
    assert set(run.kf_stamps[chosen]) == {*np.arange(5.0, 15.0), *np.arange(27.0, 37.0)}
    near = stretch_keyframes(run, [40, 41, 42, 43], map_radius_m=12.0)  # 14 and 27 s are apart: 2, too few
    assert set(run.kf_stamps[near]) == set(np.arange(14.0, 28.0))
    monkeypatch.setattr(offset_rematch, "MAP_KEYFRAMES", 4)  # the nearest 4 of those apart: 13-14 and 27-28 s
    assert set(run.kf_stamps[stretch_keyframes(run, [40, 41, 42, 43], map_radius_m=30.0)]) == {13.0, 14.0, 27.0, 28.0}
