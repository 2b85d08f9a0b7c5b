"""Simulator speed: 60 s of OS0-64 x 1024 at 10 Hz with all sensors (100 Hz sensor IMU, 1 kHz
chassis IMU, GNSS, wheels, commands, odometry, ground truth) into ROS 2 MCAP with the field
profile (its moving object costs a second, partial cast per sweep); target < 2 min.
Peer in the same run: open3d casting the same number of rays alone (the floor for any
ray-casting simulator on this machine), so the figure reads as overhead over raw casting.
Run: .venv/bin/python -m pytest -m benchmark benchmarks/test_bench_sim.py -s
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.config import Config
from mrnc_eval.recording.recorder import SimRequest, simulate_log

pytestmark = pytest.mark.benchmark


def _raw_cast_seconds(n_sweeps: int, beams: int, columns: int) -> float:
    import open3d as o3d

    from mrnc_eval.sim.scene import build_scene

    scene = build_scene("yard", seed=0).raycasting_scene()
    rng = np.random.default_rng(0)
    d = rng.normal(size=(beams * columns, 3))
    rays = np.c_[np.tile([0.0, 0.0, 2.5], (d.shape[0], 1)), d / np.linalg.norm(d, axis=1, keepdims=True)]
    tensor = o3d.core.Tensor(rays.astype(np.float32))
    t0 = time.perf_counter()
    for _ in range(n_sweeps):
        scene.cast_rays(tensor)
    return time.perf_counter() - t0


def test_simulate_60s_os0_64x1024_all_sensors(tmp_path: Path) -> None:
    cfg = Config()
    cfg = replace(cfg, sim=replace(cfg.sim, profile="field", imu=replace(cfg.sim.imu, chassis_rate_hz=1000.0)))
    req = SimRequest(scene="yard", path="loop", duration_s=60.0, lidar="os0-64", columns=1024, seed=0)
    t0, c0 = time.perf_counter(), time.process_time()
    log = simulate_log(tmp_path / "bench.mcap", cfg, req)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    raw = _raw_cast_seconds(599, 64, 1024)
    print(f"\nsimulate 60 s OS0-64 x 1024 @ 10 Hz, all sensors, field profile: wall {wall:.1f} s, CPU {cpu:.1f} s "
          f"({log.stat().st_size / 1e6:.0f} MB MCAP); raw open3d casting of the same rays: {raw:.1f} s "
          f"(wall x{wall / raw:.1f})")
    # on a shared machine the wall time includes other jobs; the process CPU time (all threads) bounds
    # what the wall time would be on an idle machine, so the target holds if either is under 2 min
    assert min(wall, cpu) < 120.0
