"""Closed-loop speed: one hour of 1 kHz control, both sides, four controllers (compiled loop),
against the identical chain in pure Python (the same source run with NUMBA_DISABLE_JIT=1 in
a subprocess: same law, same plant, same pure pursuit), timed on a short horizon in the
same run and compared per simulated second.
Run: .venv/bin/python -m pytest -m benchmark benchmarks/test_bench_control.py -s
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from mrnc_eval.config import Config
from mrnc_eval.control.closed_loop import run_closed_loop
from mrnc_eval.control.controllers import CONTROLLERS
from mrnc_eval.control.scenario import Scenario

pytestmark = pytest.mark.benchmark

PEER_SECONDS = 5.0  # simulated seconds per controller in pure Python

_PEER = """
import json, math, sys, time
import numpy as np
from mrnc_eval.config import Config
from mrnc_eval.control.closed_loop import run_closed_loop
from mrnc_eval.control.scenario import Scenario
ang = -np.pi / 2 - 2 * np.pi * np.arange(8 * 120 + 1) / 8
sc = Scenario("long", np.c_[5 * np.cos(ang), 5 * np.sin(ang)], (), (0.0, -5.0, math.pi))
cfg = Config()
out = {}
for name in sys.argv[1].split(","):
    t0 = time.perf_counter()
    tr = run_closed_loop(sc, cfg.control, cfg.robot, name, duration_s=float(sys.argv[2]), record_every=100)
    out[name] = [time.perf_counter() - t0, float(tr.x[-1])]
print(json.dumps(out))
"""


def _long_loop() -> Scenario:
    # a 5 m circle driven for an hour: 120 laps of waypoints
    ang = -np.pi / 2 - 2 * np.pi * np.arange(8 * 120 + 1) / 8
    return Scenario("long", np.c_[5 * np.cos(ang), 5 * np.sin(ang)], (), (0.0, -5.0, math.pi))


def _pure_python_seconds(seconds: float) -> dict[str, list[float]]:
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1"}
    proc = subprocess.run([sys.executable, "-c", _PEER, ",".join(CONTROLLERS), str(seconds)], env=env,
                          capture_output=True, text=True, check=True, timeout=600)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_one_hour_at_1khz_four_controllers() -> None:
    cfg = Config()
    sc = _long_loop()
    run_closed_loop(sc, cfg.control, cfg.robot, "raid", duration_s=1.0)  # compile outside the timing
    t0 = time.perf_counter()
    for name in CONTROLLERS:
        tr = run_closed_loop(sc, cfg.control, cfg.robot, name, duration_s=3600.0, record_every=100)
        assert tr.t[-1] > 3599.0
        assert not tr.completed
    wall = time.perf_counter() - t0
    peer = _pure_python_seconds(PEER_SECONDS)
    # the same law gives the same motion without the compiler
    short = {n: run_closed_loop(sc, cfg.control, cfg.robot, n, duration_s=PEER_SECONDS, record_every=100)
             for n in CONTROLLERS}
    for n in CONTROLLERS:
        assert peer[n][1] == pytest.approx(float(short[n].x[-1]), abs=1e-9), n
    peer_hour = sum(v[0] for v in peer.values()) / PEER_SECONDS * 3600.0
    print(f"\n1 h at 1 kHz x 2 sides x 4 controllers: compiled {wall:.1f} s; pure Python (same source, "
          f"NUMBA_DISABLE_JIT) {peer_hour:.0f} s extrapolated from {PEER_SECONDS:.0f} s per controller "
          f"-> {peer_hour / wall:.0f}x")
    assert wall < 60.0
    assert peer_hour / wall > 20.0


SWEEP_RUNS = 500
PEER_DRAWS = 25  # draws run serially in this process as the peer, extrapolated to SWEEP_RUNS


def test_sweep_500_runs_x_5_controllers_of_the_paper_circle() -> None:
    """control --mode sweep: 500 drawn plants x 5 controllers x the paper's 100 s circle at 1 kHz, in
    worker processes on all cores, against the serial loop (same function, this process) in the same run.
    The machine is shared: besides the wall time we report the workers' CPU time, whose share per core is
    the wall time on idle cores (the chunks are independent), and assert on that."""
    import resource

    from mrnc_eval.commands.control_sweep import run_chunk, run_sweep, summarise, sweep_table
    from mrnc_eval.control.sweep import draw_plants
    from mrnc_eval.reports.tables import render_table

    cfg = Config()
    assert cfg.control.sweep.duration_s == 100.0
    assert cfg.control.rate_hz == 1000.0
    run_sweep(cfg, CONTROLLERS, 1, 0, workers=1)  # compile / load the kernel cache outside the timing
    workers = os.cpu_count() or 1
    children0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    runs = run_sweep(cfg, CONTROLLERS, SWEEP_RUNS, 0, workers=workers)
    wall = time.perf_counter() - t0
    children1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (children1.ru_utime - children0.ru_utime) + (children1.ru_stime - children0.ru_stime)
    load = os.getloadavg()[0]
    assert len(runs) == SWEEP_RUNS * len(CONTROLLERS)
    draws = draw_plants(cfg.control.sweep, PEER_DRAWS, 0)
    t0, c0 = time.perf_counter(), time.process_time()
    serial = run_chunk(draws, CONTROLLERS, cfg, 0)
    scale = SWEEP_RUNS / PEER_DRAWS
    peer_wall, peer_cpu = (time.perf_counter() - t0) * scale, (time.process_time() - c0) * scale
    assert serial == runs[:PEER_DRAWS * len(CONTROLLERS)]  # the pool computes exactly what the loop does
    idle_wall = cpu / workers
    print(f"\nsweep {SWEEP_RUNS} runs x {len(CONTROLLERS)} controllers x 100 s at 1 kHz on {workers} worker "
          f"processes: wall {wall:.1f} s (1-min load average {load:.1f} on {os.cpu_count()} cores), worker CPU "
          f"{cpu:.1f} s = {idle_wall:.1f} s per core; serial loop (this process, extrapolated from {PEER_DRAWS} "
          f"draws): wall {peer_wall:.1f} s, CPU {peer_cpu:.1f} s -> {peer_wall / wall:.2f}x wall, "
          f"{peer_cpu / idle_wall:.2f}x on idle cores")
    print(render_table(sweep_table(summarise(runs, CONTROLLERS, cfg), cfg, SWEEP_RUNS, 0), "markdown"))
    # the wall times are printed, not asserted: with other jobs on the 2 cores (load 11.6 when measured) they
    # measure the neighbours; the CPU time of the same work does not
    assert idle_wall < 60.0
    assert peer_cpu / idle_wall > 1.3
