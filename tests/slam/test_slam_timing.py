"""Issue 19 item 11: the per-sweep timing statistics hold the per-sweep work only. numba compiles a
kernel at its first call (on a fresh install, or when its on-disk cache is stale), which once made a
stage's max 1750 ms beside a p95 of 43 ms and its mean above its p95; the replay now warms every stage
before the timed loop and reports that one-off cost apart (`warmup_ms`)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]

# Runs in a fresh interpreter (no kernel compiled in memory) with numba's cache in an empty folder
# (nothing to load from disk): the state of a fresh install. Records how many signatures each
# compiled kernel of mrnc_eval.slam has when the first sweep arrives and after the last one.
SCRIPT = r"""
import importlib, json, pkgutil, sys
from numba.core.dispatcher import Dispatcher
import mrnc_eval.slam as slam_pkg
from mrnc_eval.config import Config
from mrnc_eval.io import open_log
from mrnc_eval.slam.mapping_interval import MappingInterval
from mrnc_eval.slam.replay import run_slam

def compiled():
    out = {}
    for info in pkgutil.iter_modules(slam_pkg.__path__):
        module = importlib.import_module(f"mrnc_eval.slam.{info.name}")
        for name, obj in vars(module).items():
            if isinstance(obj, Dispatcher) and obj.__module__ == module.__name__:
                out[f"{info.name}.{name}"] = len(obj.signatures)
    out["open3d imported"] = int("open3d" in sys.modules)  # loop closure's ICP no longer needs it (slam/icp.py)
    return out

cfg = Config()
marks = {}
with open_log(sys.argv[1], cfg.io) as lg:
    out = run_slam(lg.sweeps(keep=MappingInterval(interval_s=cfg.slam.mapping_interval_s).take), lg.imu(), cfg.slam,
                   sensor_to_imu=lg.transform("os_sensor", "os_imu"),
                   progress=lambda n: marks.setdefault("first_sweep", compiled()))
marks["after_loop"] = compiled()
print(json.dumps({"marks": marks, "timing_ms": out.timing_ms, "warmup_ms": getattr(out, "warmup_ms", None)}))
"""


def test_no_kernel_compiles_inside_the_timed_loop_and_no_sweep_pays_the_warmup(yard_log: Path, tmp_path: Path) -> None:
    from mrnc_eval.commands.slam import _stage_timing
    from mrnc_eval.slam.output import SlamOutput

    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache"), "PYTHONPATH": str(REPO)}
    run = subprocess.run([sys.executable, "-c", SCRIPT, str(yard_log)], capture_output=True, text=True, env=env,
                         timeout=600, check=False)
    assert run.returncode == 0, run.stderr[-2000:]
    got = json.loads(run.stdout.strip().splitlines()[-1])
    first, after = got["marks"]["first_sweep"], got["marks"]["after_loop"]
    # every kernel the loop calls was compiled before its first sweep, and open3d is never imported
    compiled_in_loop = {k: after[k] - first.get(k, 0) for k in after if after[k] != first.get(k, 0)}
    assert not compiled_in_loop, f"compiled or imported inside the timed loop: {compiled_in_loop}"
    assert sum(after.values()) >= 7, after  # the check saw the SLAM's kernels
    assert after["open3d imported"] == 0
    # the one-off cost is reported apart, per stage; with an empty cache it is compilation, seconds
    warm = got["warmup_ms"]
    # (range image, deskew and features are C, slam/_prep_kernels.c: no first-call cost to report)
    assert set(warm) == {"matching", "loop"}
    stats = _stage_timing(SlamOutput(stamps=np.zeros(0), poses=np.zeros((0, 4, 4)), kf_stamps=np.zeros(0),
                                     kf_poses=np.zeros((0, 4, 4)), map_points=np.zeros((0, 3)),
                                     timing_ms=got["timing_ms"], events=[], warnings=[], n_sweeps=0, wall_s=0.0))
    for stage in ("matching",):  # the stage with numba kernels that works on every sweep
        s = stats[stage]
        # before the warm-up, one sweep's matching held the compilation: max 4955 ms beside p95 117 ms and a
        # mean (254 ms) above the p95; now no sweep comes near the one-off cost (seconds with an empty cache).
        # (mean <= p95 itself is not asserted: matching takes ~5 ms a sweep on this log, so one scheduling
        # hiccup on a shared machine can lift the mean above the p95 without any compilation.)
        assert s["p95"] <= s["max"] < warm[stage], (stage, s, warm[stage])
