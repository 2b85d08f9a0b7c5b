"""CPU time per sweep of the sweep stream alone (`LogReader.sweeps()`: reading, decompressing,
checking and decoding the clouds; what the SLAM's reader thread does before the projection),
after the overview pass the slam command runs first. docs/performance.md, "The reader".

    PYTHONPATH=. python benchmarks/read_sweeps.py LOG
    PYTHONPATH=. python -m cProfile -s tottime benchmarks/read_sweeps.py LOG | head -30
"""

from __future__ import annotations

import os
import resource
import sys
import time
from pathlib import Path

from mrnc_eval.io import open_log


def _cpu_s() -> float:
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


def main(log: Path) -> None:
    with open_log(log) as lg:
        assert lg.topics  # the overview pass, as `slam` runs it before the sweeps
        load0 = os.getloadavg()[0]
        cpu0, t0 = _cpu_s(), time.perf_counter()
        n = points = 0
        for sweep in lg.sweeps():
            n += 1
            points += len(sweep)
        cpu, wall = _cpu_s() - cpu0, time.perf_counter() - t0
    print(f"{log.name}: {n} sweeps, {points} points; sweep stream CPU {cpu:.3f} s = {1e3 * cpu / max(n, 1):.2f} ms "
          f"a sweep, wall {wall:.3f} s; load average {load0:.2f} -> {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
