"""benchmarks/no_wheel_trace.py's pure parts: what it counts as a multipath jump on the fixes, and the
end drift an ENU -> map alignment's yaw error makes on a straight drive."""

from __future__ import annotations

import numpy as np

from benchmarks.no_wheel_trace import alignment_row, jump_stats
from mrnc_eval.data import Trajectory


def _fix_errors(seed: int, jump_m: float) -> np.ndarray:
    """200 fixes' errors (m): 0.3 m white noise, and jump_m held on fixes 50-89 (8 s at 5 Hz)."""
    err = np.random.default_rng(seed).normal(0.0, 0.3, (200, 2))
    err[50:90] += jump_m * np.array([0.6, 0.8])
    return err


def test_a_held_jump_is_counted_and_clean_noise_mostly_is_not() -> None:
    """A 1.5 m jump on 40 of 200 fixes (0.20 of the time): read as 0.21-0.30 (measured, 20 noise draws;
    the surplus is the white noise's own false reads), every jumped fix the filter took counted; white
    noise alone (the negative control) reads as a jump on 0.5-10 % of the fixes (the 1 s median's tail
    beyond 0.4 m): the table's "time with a jump" is good to about 5 points."""
    taken, held = np.ones(200, bool), np.zeros(200, bool)
    taken[50:53] = False  # the filter gated the jump's first three fixes
    for seed in range(20):
        s = jump_stats(_fix_errors(seed, 1.5), taken, held)
        assert 0.19 <= s["jumped"] <= 0.4, seed
        assert s["jumped_taken"] == s["jumped_n"] - 3, seed
        clean = jump_stats(_fix_errors(seed, 0.0), taken, held)
        assert clean["jumped"] <= 0.15, seed
        assert s["jumped"] >= clean["jumped"] + 0.1, seed
        assert clean["clean_out"] <= 3, seed


def _straight(yaw_deg: float) -> Trajectory:
    """40 s along a heading at 1 m/s, heading yaw_deg, 10 Hz."""
    t = np.arange(0.0, 40.0, 0.1)
    yaw = np.radians(yaw_deg)
    pos = np.c_[t * np.cos(yaw), t * np.sin(yaw), np.zeros_like(t)]
    quat = np.tile([0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)], (len(t), 1))
    return Trajectory(stamps=t, positions=pos, quat_xyzw=quat)


def test_the_alignments_yaw_error_is_read_against_the_truths_heading_in_the_map() -> None:
    """Truth heading 30 deg in the world (= ENU), the map's first pose at 0 deg: the ideal ENU -> map yaw
    is -30 deg. An alignment of -40 deg is 10 deg off, which alone moves the end of a 40 m drive by
    2 x 40 x sin(5 deg) = 6.97 m; the ideal alignment (negative control) moves it by nothing."""
    gt, est = _straight(30.0), _straight(0.0)
    length = float(np.linalg.norm(gt.positions[-1, :2] - gt.positions[0, :2]))
    off = alignment_row({"events": [{"kind": "gps", "data": {"enu_to_map_yaw_deg": -40.0}}]}, gt, est)
    assert abs(off["align_err"] + 10.0) < 1e-6
    assert abs(off["align_drift"] - 2 * length * np.sin(np.radians(5.0))) < 1e-6
    assert abs(off["chain_yaw_end"]) < 1e-6  # both headings constant
    ideal = alignment_row({"events": [{"kind": "gps", "data": {"enu_to_map_yaw_deg": -30.0}}]}, gt, est)
    assert abs(ideal["align_err"]) < 1e-6
    assert ideal["align_drift"] < 1e-6
