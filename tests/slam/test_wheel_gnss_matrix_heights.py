"""benchmarks/wheel_gnss_matrix.py's height columns (docs/simulation.md, "holding the open line's z"):
a base_link pitched by its mount on a level path is an end z that heights cannot hold; a map tilted
with its first pose is no end z, and holding the heights makes one."""

from __future__ import annotations

import dataclasses

import numpy as np

from benchmarks.wheel_gnss_matrix import height_checks
from mrnc_eval.data import Trajectory
from mrnc_eval.evaluation.ape import ape
from mrnc_eval.geometry import rotation


def _level_line() -> Trajectory:
    """40 s along x at 1 m/s, level, 10 Hz."""
    t = np.arange(0.0, 40.05, 0.1)
    return Trajectory(stamps=t, positions=np.c_[t, np.zeros((t.size, 2))], quat_xyzw=np.tile([0.0, 0.0, 0.0, 1.0],
                                                                                             (t.size, 1)))


def _turned(tr: Trajectory, pitch_deg: float, *, positions_too: bool) -> Trajectory:
    """Every attitude pitched by pitch_deg (and, positions_too, the path turned with it about the start)."""
    r = rotation.from_rpy(np.radians([0.0, pitch_deg, 0.0]))
    quat = rotation.matrix_to_quat(r @ rotation.quat_to_matrix(tr.quat_xyzw))
    pos = (tr.positions - tr.positions[0]) @ r.T + tr.positions[0] if positions_too else tr.positions
    return dataclasses.replace(tr, positions=pos, quat_xyzw=quat)


def _end_z(gt: Trajectory, est: Trajectory) -> float:
    return float(ape(gt, est, align="origin", max_diff=0.05).decompose().vertical_m[-1])


def test_a_pitched_mount_is_an_end_z_that_the_truths_heights_keep() -> None:
    """Base pitched 0.4 deg, path level (the open line's case): 40 m x sin(0.4 deg) = 0.279 m of end z, no
    map climb, and the same z with every height the truth's."""
    gt = _level_line()
    est = _turned(gt, -0.4, positions_too=False)
    h = height_checks(gt, est)
    expected = 40.0 * np.sin(np.radians(0.4))
    assert abs(h["map_climb_deg"]) < 1e-6
    assert abs(abs(_end_z(gt, est)) - expected) < 0.01 * expected
    assert abs(abs(h["z_height_held_m"]) - expected) < 0.01 * expected


def test_a_map_tilted_with_its_first_pose_is_no_end_z_until_the_heights_are_held() -> None:
    """Map tilted 1 deg with the first pose (an IMU start's tilt): the climb reads 1 deg, the origin
    alignment takes the end z out, and the truth's heights put 40 m x sin(1 deg) = 0.70 m back in."""
    gt = _level_line()
    est = _turned(gt, 1.0, positions_too=True)
    h = height_checks(gt, est)
    assert abs(abs(h["map_climb_deg"]) - 1.0) < 0.01
    assert abs(_end_z(gt, est)) < 1e-6
    expected = 40.0 * np.sin(np.radians(1.0))
    assert abs(abs(h["z_height_held_m"]) - expected) < 0.01 * expected


def test_the_truth_against_itself_reads_nothing() -> None:
    """Negative control."""
    gt = _level_line()
    h = height_checks(gt, gt)
    assert abs(h["map_climb_deg"]) < 1e-9
    assert abs(h["z_height_held_m"]) < 1e-9
