"""How many threads a lio run uses (slam.threads) and, for one thread, holding OpenMP (pykdtree's
KD-tree queries) to one as well, so `--threads 1` is a serial run to compare against."""

from __future__ import annotations

import ctypes
import os
from collections.abc import Iterator
from contextlib import contextmanager


def run_threads(configured: int) -> int:
    """slam.threads, 0 meaning every core the process may run on."""
    if configured > 0:
        return configured
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def _openmp_libraries() -> list[ctypes.CDLL]:
    """The OpenMP runtimes loaded in this process (pykdtree ships its own libgomp)."""
    import pykdtree.kdtree  # noqa: F401 - loads its libgomp, the one whose teams we hold

    try:
        with open("/proc/self/maps", encoding="ascii", errors="replace") as f:
            fields = (line.split(maxsplit=5) for line in f if "libgomp" in line and "/" in line)
            paths = {f[5].removesuffix(" (deleted)").strip() for f in fields if len(f) == 6}
    except OSError:  # not on Linux: left as it is
        return []
    libs = []
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
            lib.omp_get_max_threads.restype = ctypes.c_int
            libs.append(lib)
        except (OSError, AttributeError):
            continue
    return libs


@contextmanager
def openmp_threads(n: int | None) -> Iterator[None]:
    """OpenMP teams started from this thread run on at most n threads inside the block; None: as
    configured (OMP_NUM_THREADS, else every core). Restored afterwards. An explicit OMP_NUM_THREADS
    in the environment wins, as for OpenMP itself."""
    libs = _openmp_libraries() if n is not None and "OMP_NUM_THREADS" not in os.environ else []
    before = [lib.omp_get_max_threads() for lib in libs]
    for lib in libs:
        lib.omp_set_num_threads(ctypes.c_int(n or 1))
    try:
        yield
    finally:
        for lib, m in zip(libs, before, strict=True):
            lib.omp_set_num_threads(ctypes.c_int(m))
