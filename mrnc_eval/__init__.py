"""mrnc-eval: offline log processing and evaluation for skid-steer field robots."""

import os

__version__ = "0.1.0"

# pykdtree (the SLAM's nearest-neighbour search) runs its queries on OpenMP threads, and libgomp's
# default active wait keeps them spinning after each query, taking the core the main thread needs:
# on 2 shared cores that doubled the SLAM's CPU time (benchmarks/test_bench_slam.py). Passive
# waiting sleeps instead. libgomp reads this once, when it loads, so it is set here, before any
# module of the package can import pykdtree; an explicit setting in the environment wins.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
