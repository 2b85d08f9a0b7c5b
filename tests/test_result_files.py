"""Issue 19, finding results: OUT/latest points at the newest run, poses also as KITTI."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mrnc_eval.data import Trajectory
from mrnc_eval.io.trajectory_files import read_kitti, write_kitti
from mrnc_eval.results import link_latest


def test_latest_follows_the_newest_run(tmp_path: Path) -> None:
    for name in ("run-1", "run-2"):
        (tmp_path / name).mkdir()
        link = link_latest(tmp_path / name)
        assert link == tmp_path / "latest"
        assert link.resolve() == (tmp_path / name).resolve()
        assert not link.readlink().is_absolute()  # the output root can be moved
    assert sorted(p.name for p in tmp_path.iterdir()) == ["latest", "run-1", "run-2"]


def test_kitti_poses_round_trip_through_the_reader(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    q = rng.normal(size=(5, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= np.sign(q[:, 3:4])
    traj = Trajectory(np.arange(5.0) * 0.1, rng.normal(size=(5, 3)), q, name="est")
    write_kitti(tmp_path / "trajectory.kitti", traj)
    back = read_kitti(tmp_path / "trajectory.kitti")
    np.testing.assert_allclose(back.positions, traj.positions, atol=1e-8)
    np.testing.assert_allclose(np.abs(np.sum(back.quat_xyzw * q, axis=1)), 1.0, atol=1e-8)
