"""Simulator speed (60 s of OS0-64 x 1024 at 10 Hz, all sensors; target < 2 min) and SLAM
real-time factor on 60 s of OS0-128 x 1024 at 10 Hz, side by side with kiss-icp in the same run.
Run: .venv/bin/python -m pytest -m benchmark benchmarks/test_bench_sim_slam.py -s
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from mrnc_eval.config import Config
from mrnc_eval.sim.recorder import SimRequest, simulate_log

pytestmark = pytest.mark.benchmark


def test_simulate_60s_os0_64(tmp_path: Path) -> None:
    t0 = time.perf_counter()
    log = simulate_log(tmp_path / "b.mcap", Config(), SimRequest(scene="yard", path="loop", duration_s=60.0,
                                                                  lidar="os0-64", columns=1024, seed=0))
    wall = time.perf_counter() - t0
    print(f"\nsimulate 60 s OS0-64 x 1024 @ 10 Hz, all sensors: {wall:.1f} s, {log.stat().st_size / 1e6:.0f} MB")
    assert wall < 120.0


def test_slam_rtf_vs_kiss_icp(tmp_path: Path) -> None:
    from mrnc_eval.pipelines.slam import run_log

    log = simulate_log(tmp_path / "s.mcap", Config(), SimRequest(scene="forest", path="loop", duration_s=60.0,
                                                                  lidar="os0-128", columns=1024, seed=0))
    lio = run_log(log, Config(), tmp_path / "lio", method="lio")
    kiss = run_log(log, Config(), tmp_path / "kiss", method="kiss-icp")
    val = lambda r, n: r.metric(n).value  # noqa: E731
    print(f"\nSLAM 60 s OS0-128 x 1024 @ 10 Hz: lio RTF {val(lio, 'rtf'):.2f} APE {val(lio, 'ape_rmse_m'):.3f} m "
          f"({val(lio, 'loop_closures')} loops) | kiss-icp RTF {val(kiss, 'rtf'):.2f} APE {val(kiss, 'ape_rmse_m'):.3f} m")
    print("per-stage ms (mean/p95):", {k: (round(v['mean'], 1), round(v['p95'], 1)) for k, v in lio.extra['timing_ms'].items()})
    assert val(lio, "ape_rmse_m") < 0.10
    assert val(lio, "rtf") >= 1.0
    assert val(lio, "rtf") > val(kiss, "rtf")
