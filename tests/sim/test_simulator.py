"""Simulator: sensors agree with ground truth; determinism; every container reads back."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mrnc_eval.config import Config
from mrnc_eval.io import open_log
from mrnc_eval.io.trajectory_files import read_tum
from mrnc_eval.sim.motion import BodyMotion
from mrnc_eval.sim.recorder import SimRequest, gt_tum_path, simulate_log
from mrnc_eval.sim.scene import Terrain, build_scene


def _quiet(cfg: Config) -> Config:
    imu = replace(cfg.sim.imu, acc_noise_density=0.0, gyro_noise_density=0.0, acc_bias_walk=0.0, gyro_bias_walk=0.0)
    lidar = replace(cfg.sim.lidar, range_noise_m=0.0)
    return replace(cfg, sim=replace(cfg.sim, imu=imu, lidar=lidar))


def test_static_imu_measures_gravity_in_the_body_frame() -> None:
    t = np.linspace(0, 10, 1001)
    terrain = Terrain(0.3, 0.02, 3)
    still = BodyMotion(t, np.full_like(t, 4.0), np.full_like(t, -2.0), np.full_like(t, 0.7), terrain)
    f, w, _, r = still.imu_kinematics(t[5:-5], np.array([1.2, 0.0, 1.9]))
    np.testing.assert_allclose(f, r.inv().apply(np.tile([0, 0, 9.80665], (f.shape[0], 1))), atol=1e-6)
    assert np.linalg.norm(f.mean(axis=0)) == pytest.approx(9.80665, abs=1e-6)
    np.testing.assert_allclose(w, 0.0, atol=1e-9)


def test_integrated_ideal_imu_reproduces_ground_truth() -> None:
    cfg = Config()
    from mrnc_eval.control.closed_loop import run_closed_loop
    from mrnc_eval.control.scenario import paper_circle_scenario

    tr = run_closed_loop(paper_circle_scenario(cfg.control), cfg.control, cfg.robot, "raid", duration_s=12.0)
    motion = BodyMotion(tr.t, tr.x, tr.y, np.unwrap(tr.yaw), Terrain(0.3, 0.02, 1))
    dt = 1e-3
    times = np.arange(5.0, 7.0, dt)
    lever = np.array([1.2, 0.0, 1.9])
    f, w, p0, r0 = motion.imu_kinematics(times, lever)
    # strapdown integration (2 s at 1 kHz) from the true initial state
    _, rot = motion.pose(times[:1])
    rot = rot[0]
    p = p0[0].copy()
    v = (motion.imu_kinematics(times[:1] + 1e-4, lever)[2][0] - motion.imu_kinematics(times[:1] - 1e-4, lever)[2][0]) / 2e-4
    g = np.array([0, 0, -9.80665])
    for k in range(times.size - 1):
        a = rot.apply(f[k]) + g
        p = p + v * dt + 0.5 * a * dt * dt
        v = v + a * dt
        rot = rot * Rotation.from_rotvec(w[k] * dt)
    assert np.linalg.norm(p - p0[-1]) < 0.01
    assert (rot.inv() * r0[-1]).magnitude() < 1e-3


def test_lidar_points_of_a_wall_lie_on_it(tmp_path: Path) -> None:
    cfg = _quiet(Config())
    log = simulate_log(tmp_path / "corr.mcap", cfg, SimRequest(scene="corridor", path="line", duration_s=3.0,
                                                                 lidar="os0-32", columns=512, seed=1))
    with open_log(log) as lg:
        sweeps = list(lg.sweeps())
        gt = lg.ground_truth()
        base_to_sensor = lg.transform("base_link", "os_sensor")
    from scipy.spatial.transform import Slerp

    slerp = Slerp(gt.stamps, Rotation.from_quat(gt.quat_xyzw))
    on_wall = 0
    for s in sweeps[5:8]:
        t = s.stamp + s.point_time.astype(float)  # each point at its own time (motion distortion)
        pos = np.stack([np.interp(t, gt.stamps, gt.positions[:, k]) for k in range(3)], axis=1)
        p_base = s.points.astype(float) @ base_to_sensor[:3, :3].T + base_to_sensor[:3, 3]
        world = slerp(t).apply(p_base) + pos
        wall = np.abs(np.abs(world[:, 1]) - 3.85) < 0.3  # inner faces at |y| = 4.0 - 0.15
        assert wall.sum() > 200
        on_wall += wall.sum()
        assert np.percentile(np.abs(np.abs(world[wall, 1]) - 3.85), 95) < 0.02
    assert on_wall > 0


def test_same_seed_gives_identical_logs_and_containers_read_back(tmp_path: Path) -> None:
    cfg = Config()
    req = SimRequest(scene="yard", path="circle", duration_s=2.0, lidar="os0-32", columns=512, seed=4)
    for fmt, name in (("mcap", "a.mcap"), ("bag", "a.bag"), ("db3", "a.db3")):
        one = simulate_log(tmp_path / "1" / name, cfg, replace(req, fmt=fmt))
        two = simulate_log(tmp_path / "2" / name, cfg, replace(req, fmt=fmt))
        if fmt != "db3":  # sqlite3 pages are not byte-stable; its content is
            assert one.read_bytes() == two.read_bytes()
        with open_log(one) as lg:
            assert lg.roles["lidar"] == "/ouster/points" and lg.roles["ground_truth"] == "/ground_truth"
            assert len(list(lg.sweeps())) == 19
            gt = lg.ground_truth()
        tum = read_tum(gt_tum_path(one))
        np.testing.assert_allclose(tum.positions, gt.positions, atol=1e-6)
    other = simulate_log(tmp_path / "3" / "a.mcap", cfg, replace(req, seed=5))
    assert other.read_bytes() != (tmp_path / "1" / "a.mcap").read_bytes()


def test_scenes_build() -> None:
    for name in ("yard", "forest", "corridor", "field"):
        assert len(build_scene(name, seed=0).vertices) >= 1
