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
