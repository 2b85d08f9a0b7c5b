"""Closed-loop speed: one hour of 1 kHz control, both sides, four controllers (compiled loop),
against the same chain stepped from Python through the controller classes (the peer), measured
on a shorter horizon in the same run and compared per simulated second.
Run: .venv/bin/python -m pytest -m benchmark benchmarks/test_bench_control.py -s
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from mrnc_eval.config import Config
from mrnc_eval.control.closed_loop import run_closed_loop
from mrnc_eval.control.controllers import CONTROLLERS, WheelController
from mrnc_eval.control.scenario import Scenario

pytestmark = pytest.mark.benchmark


def _long_loop() -> Scenario:
    # a 5 m circle driven for an hour: 115 laps of waypoints
    ang = -np.pi / 2 - 2 * np.pi * np.arange(8 * 120 + 1) / 8
    wp = np.c_[5 * np.cos(ang), 5 * np.sin(ang)]
    return Scenario("long", wp, (), (0.0, -5.0, math.pi))


def _python_peer(cfg: Config, seconds: float) -> float:
    """Wheel loop of one controller and side in plain Python (same kernels, stepped per call)."""
    c = WheelController("raid", cfg.control)
    v, dt = 0.0, 1e-3
    t0 = time.perf_counter()
    for k in range(int(seconds / dt)):
        u, _ = c.step(k * dt, 0.3, 0.0, v, dt)
        v += dt / 0.4 * (u / 3000.0 - v)
    return time.perf_counter() - t0


def test_one_hour_at_1khz_four_controllers() -> None:
    cfg = Config()
    sc = _long_loop()
    run_closed_loop(sc, cfg.control, cfg.robot, "raid", duration_s=1.0)  # compile outside the timing
    t0 = time.perf_counter()
    for name in CONTROLLERS:
        tr = run_closed_loop(sc, cfg.control, cfg.robot, name, duration_s=3600.0, record_every=100)
        assert tr.t[-1] > 3599.0
    wall = time.perf_counter() - t0
    peer = _python_peer(cfg, 20.0) / 20.0 * 3600.0 * 2 * len(CONTROLLERS)  # extrapolated, wheel loop only
    print(f"\n1 h at 1 kHz x 2 sides x 4 controllers: {wall:.1f} s compiled; "
          f"Python-stepped wheel loop alone would take ~{peer:.0f} s ({peer / wall:.0f}x)")
    assert wall < 60.0
    assert peer / wall > 2.0
