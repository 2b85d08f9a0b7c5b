"""SLAM speed: real-time factor on 60 s of simulated OS0-128 x 1024 at 10 Hz (forest loop), LIO
replay with loop closure on, side by side with kiss-icp in the same run on the same log and the
same readers, with the per-stage profile. Run:
    .venv/bin/python -m pytest -m benchmark benchmarks/test_bench_slam.py -s
Set MRNC_BENCH_SLAM_LOG to an existing log to skip the simulation (about 1 minute, 1.2 GB).

Both methods are warmed up on the committed sample log first, so numba's one-off compilation
(about 15 s on a fresh install, then cached on disk) is not counted against either.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from mrnc_eval.config import Config

pytestmark = pytest.mark.benchmark
SAMPLE = Path(__file__).resolve().parents[1] / "sample_logs" / "loop_forest_ros1.bag"


@pytest.fixture(scope="module")
def log_60s(tmp_path_factory: pytest.TempPathFactory) -> Path:
    given = os.environ.get("MRNC_BENCH_SLAM_LOG")
    if given:
        return Path(given)
    from mrnc_eval.sim.recorder import SimRequest, simulate_log

    return simulate_log(tmp_path_factory.mktemp("bench") / "forest60.mcap", Config(),
                        SimRequest(scene="forest", path="loop", duration_s=60.0, lidar="os0-128", columns=1024, seed=0))


def test_slam_rtf_vs_kiss_icp(log_60s: Path, tmp_path: Path) -> None:
    from mrnc_eval.commands.slam import run_log

    for method in ("lio", "kiss-icp"):  # warm-up: compile and import outside the measurement
        run_log(SAMPLE, Config(), tmp_path / f"warm-{method}", method=method)
    runs = {}
    for method in ("lio", "kiss-icp"):
        t0 = time.perf_counter()
        r = run_log(log_60s, Config(), tmp_path / method, method=method)
        runs[method] = (r, time.perf_counter() - t0)
    val = lambda r, n: r.metric(n).value  # noqa: E731
    print(f"\n60 s OS0-128 x 1024 @ 10 Hz ({log_60s.name}, {log_60s.stat().st_size / 1e9:.2f} GB)")
    print("| method | sweeps processed | SLAM wall s | RTF (SLAM) | end-to-end wall s | RTF (end-to-end) "
          "| APE RMSE m | loops |")
    print("|---|---|---|---|---|---|---|---|")
    for m, (r, wall) in runs.items():
        print(f"| {m} | {val(r, 'sweeps_processed')} | {r.extra['wall_s']:.1f} | {val(r, 'rtf'):.2f} | {wall:.1f} | "
              f"{val(r, 'rtf_end_to_end'):.2f} | {val(r, 'ape_rmse_m'):.4f} | {val(r, 'loop_closures')} |")
    lio, kiss = runs["lio"][0], runs["kiss-icp"][0]
    print("lio per-stage ms per mapped sweep (mean / p95 / max):")
    for stage, v in lio.extra["timing_ms"].items():
        print(f"  {stage:10s} {v['mean']:7.1f} {v['p95']:7.1f} {v['max']:7.1f}")
    assert val(lio, "loop_closures") >= 1  # loop closure on and used
    assert val(lio, "ape_rmse_m") < 0.10
    assert val(lio, "rtf_end_to_end") >= 1.0  # reading the log included
    assert runs["lio"][1] < runs["kiss-icp"][1]
    assert val(lio, "ape_rmse_m") < val(kiss, "ape_rmse_m")


def test_nearest_neighbour_backends_on_a_local_map() -> None:
    """Why scan-to-map uses pykdtree: build + 5-NN query on a local map of the size LIO-SAM keeps
    (the voxelised clouds of 40 sweeps of the circle sample log, ~1e5 points; queries = one
    sweep's features), against scipy's cKDTree (2 workers) and open3d's KDTreeFlann."""
    import numpy as np
    import open3d as o3d
    from pykdtree.kdtree import KDTree
    from scipy.spatial import cKDTree

    from mrnc_eval.io import open_log
    from mrnc_eval.slam.features import voxel_downsample

    with open_log(SAMPLE.parent / "circle_soft_ground.mcap") as lg:
        clouds = [s.points.astype(np.float64) for _, s in zip(range(40), lg.sweeps(), strict=False)]
    rng = np.random.default_rng(0)
    cloud = np.vstack([c + rng.normal(0, 0.05, c.shape) for c in clouds])  # 40 slightly different views
    local_map = voxel_downsample(cloud, 0.2)
    queries = voxel_downsample(clouds[-1], 0.4)

    def scipy_(m, q):
        return cKDTree(m).query(q, k=5, workers=2)[1]

    def pyk(m, q):
        return KDTree(m).query(q, k=5)[1]

    def o3d_(m, q):
        tree = o3d.geometry.KDTreeFlann(o3d.geometry.PointCloud(o3d.utility.Vector3dVector(m)))
        return np.array([np.asarray(tree.search_knn_vector_3d(p, 5)[1]) for p in q])

    times = {}
    for name, fn in (("scipy cKDTree", scipy_), ("pykdtree", pyk), ("open3d KDTreeFlann", o3d_)):
        fn(local_map, queries)  # warm-up
        t0 = time.perf_counter()
        for _ in range(5):
            idx = fn(local_map, queries)
        times[name] = (time.perf_counter() - t0) / 5 * 1e3
        assert idx.shape == (len(queries), 5)
    print(f"\nlocal map {len(local_map)} points, {len(queries)} queries, 5-NN, build + query (ms):")
    for name, ms in times.items():
        print(f"  {name:20s} {ms:7.1f}")
    assert times["pykdtree"] < times["scipy cKDTree"]
