"""Per-stage wall and CPU time per mapped sweep of `mrnc-eval slam LOG` (lio), in one fresh process:
the stage timings the replay records (slam/output.py: `timing_ms`, `cpu_ms`), first sweep left out
as in the result's metrics, plus the run's wall and CPU time and the load average it ran under.
Prints a Markdown table (docs/performance.md, "SLAM, where the time goes").

    PYTHONPATH=. python benchmarks/slam_stages.py LOG [MAPPING_INTERVAL_S [THREADS]]

CPU per stage is the CPU time of the thread that ran the stage: with THREADS = 1 every stage runs on
the main thread (OpenMP held to it too), so the column adds up to the run; with more, "read" is only
the wait for the reader thread, and its decoding shows in "other threads" below the table.
"""

from __future__ import annotations

import os
import resource
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

import mrnc_eval  # noqa: F401 - first: sets OpenMP's wait policy before pykdtree loads
from mrnc_eval.commands import slam
from mrnc_eval.config import Config, replace_path
from mrnc_eval.slam import replay
from mrnc_eval.slam.output import STAGES, SlamOutput


def _cpu_s() -> float:
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


def main(log: Path, interval: float, threads: int) -> None:
    captured: list[SlamOutput] = []
    run_slam = replay.run_slam

    def capture(*args: Any, **kwargs: Any) -> SlamOutput:
        out = run_slam(*args, **kwargs)
        captured.append(out)
        return out

    replay.run_slam = capture  # type: ignore[assignment]  # commands/slam.py imports it when it runs
    cfg = replace_path(Config(), "slam.mapping_interval_s", interval)
    if hasattr(cfg.slam, "threads"):  # not before issue 30 (run against an older checkout for "before")
        cfg = replace_path(cfg, "slam.threads", threads)
    load0 = os.getloadavg()[0]
    cpu0, main0, t0 = _cpu_s(), time.thread_time(), time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        slam.run_log(log, cfg, Path(tmp), method="lio")
    wall, cpu, main_cpu = time.perf_counter() - t0, _cpu_s() - cpu0, time.thread_time() - main0
    out = captured[0]
    print(f"{log.name}, slam.mapping_interval_s={interval:g}, slam.threads={threads}: {out.stamps.size} sweeps mapped; "
          f"load average {load0:.2f} -> {os.getloadavg()[0]:.2f}")
    print("| stage | wall ms/sweep | CPU ms/sweep |\n|---|---|---|")
    for stage in STAGES:
        w = np.asarray(out.timing_ms[stage][1:] or [0.0])
        c = np.asarray(getattr(out, "cpu_ms", {}).get(stage, [])[1:] or [0.0])  # none before issue 30
        print(f"| {stage} | {w.mean():.1f} | {c.mean():.1f} |")
    per = {s: float(np.sum(out.timing_ms[s])) / 1e3 for s in STAGES}
    print(f"run_log: wall {wall:.2f} s, CPU {cpu:.2f} s (main thread {main_cpu:.2f} s, other threads "
          f"{cpu - main_cpu:.2f} s); mapping loop wall {out.wall_s:.2f} s, warm-up "
          f"{sum(out.warmup_ms.values()):.0f} ms; stage sums (s): " + ", ".join(f"{s} {v:.2f}" for s, v in per.items()))


if __name__ == "__main__":
    main(Path(sys.argv[1]), float(sys.argv[2]) if len(sys.argv) > 2 else 0.0,
         int(sys.argv[3]) if len(sys.argv) > 3 else 0)
