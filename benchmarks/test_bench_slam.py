"""SLAM speed and memory at equal work, side by side in one run on one log: lio at LIO-SAM's
mapping rate (slam.mapping_interval_s = 0.15 s: every other sweep of a 10 Hz sensor, 5 Hz), lio mapping
every sweep (0 s) on every core and with --threads 1 (the serial run), and kiss-icp (every sweep), on a
simulated OS0-128 x 1024 10 Hz forest loop
(field sensor profile). Every RTF is printed with its mapping rate. Run:
    .venv/bin/python -m pytest -m benchmark benchmarks/test_bench_slam.py -s
MRNC_BENCH_SLAM_LOG=<log> uses an existing log (a 30 s one is simulated otherwise: ~2 minutes,
~600 MB); MRNC_BENCH_SLAM_SECONDS sets the simulated duration.

Each run is its own process, so memory is its own: "imports" is the resident size after importing
what that method's run imports (RUN_IMPORTS; lio: numpy, gtsam, pykdtree; no numba, scipy or open3d)
and before reading the log, "run holds" is the peak resident size minus that, "peak" the whole peak.
kiss-icp runs twice: inside mrnc-eval (`--method kiss-icp`: the same reader and imports as lio) and
as its own `kiss_icp_pipeline` command on the log's clouds written as .bin scans (its peer peak).
"CPU s" is the process's user + system time over all its threads (decoding, OpenMP, TBB) for the
same span as "wall s": on a shared machine it moves less with the load than the wall time does.
Both methods are warmed up on the committed sample log first (numba's one-off compilation, then
cached on disk).

Growth per 100 keyframes (test_slam_memory_growth_per_100_keyframes) needs a long log with many
keyframes, which at full resolution would be ~12 GB: keyframes come by distance and angle, not by
sweep count, so it runs on a cheap 10-minute log instead (MRNC_BENCH_SLAM_GROWTH_LOG, else
simulated: forest, loop of sim.path_size_m = 80 m in a scene stretched x4, OS0-64 x 1024 clouds
recorded at 1 Hz, ideal profile, ~560 MB, a few minutes; OS0-32 x 512 is too sparse there and the
SLAM diverges):
the resident size sampled at every keyframe, a line fitted over the second half of the run.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.cold_start import scans_folder
from mrnc_eval.config import Config

pytestmark = pytest.mark.benchmark
SAMPLE = Path(__file__).resolve().parents[1] / "sample_logs" / "loop_forest.bag"
# name -> (method, slam.mapping_interval_s, slam.threads: 0 = every core, 1 = the serial run)
RUNS = {"lio @ 0.15 s (LIO-SAM rate)": ("lio", 0.15, 0), "lio @ every sweep": ("lio", 0.0, 0),
        "lio @ every sweep, --threads 1": ("lio", 0.0, 1), "kiss-icp @ every sweep": ("kiss-icp", 0.0, 0)}
REPEATS = 3  # alternating rounds; each row is the median run (by wall time) of its three
# lio mapping every sweep against kiss-icp at equal work, wall time, same session: issue 30 asks >= 3x on a
# quiet 2-core machine. Measured (load 0.8-1.5, main 87d110f, the SLAM's kernels in C and the one-pass
# reader): 4.03x against kiss-icp in mrnc-eval, 3.53x against kiss_icp_pipeline (4.30x in CPU time);
# under load the ratio moves (docs/performance.md), so run it on a quiet machine.
MIN_WALL_RATIO = 3.0

# One run in a fresh interpreter: imports first (measured), then the log; RSS sampled per keyframe.
# "Imports" are what that method's run imports (RUN_IMPORTS), no more (until issue 30 every run
# imported open3d here, 180 MB that no run needs); the run is checked to import no other heavy
# module (HEAVY) on its own, so imports + run holds = peak is the whole process.
RUN_IMPORTS = {"lio": ("mrnc_eval.commands.slam", "mrnc_eval.slam.replay", "gtsam", "pykdtree.kdtree"),
               "kiss-icp": ("mrnc_eval.commands.slam", "mrnc_eval.slam.range_image", "kiss_icp.kiss_icp",
                            "kiss_icp.config")}
HEAVY = ("open3d", "gtsam", "numba", "scipy", "pykdtree", "kiss_icp", "matplotlib", "pandas", "weasyprint", "dask")
_RUN = r"""
import importlib, json, resource, sys, time
def rss_mb():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize() / 1e6
bare = rss_mb()
import mrnc_eval  # first, as in every entry point: it sets OpenMP's wait policy before pykdtree loads
imports, heavy = json.loads(sys.argv[5]), json.loads(sys.argv[6])
for name in imports:
    importlib.import_module(name)
from mrnc_eval.commands import slam
from mrnc_eval.config import Config, replace_path
from mrnc_eval.slam import graph as graph_module
after_imports = rss_mb()
heavy_before = sorted({m.split(".")[0] for m in sys.modules} & set(heavy))
samples = []
add = graph_module.KeyframeGraph.add_keyframe
def add_and_sample(self, *args, **kwargs):
    out = add(self, *args, **kwargs)
    samples.append((len(self.poses), rss_mb()))
    return out
graph_module.KeyframeGraph.add_keyframe = add_and_sample
log, out_dir, method, interval, threads = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4]), int(sys.argv[7])
cfg = replace_path(replace_path(Config(), "slam.mapping_interval_s", interval), "slam.threads", threads)
ru0 = resource.getrusage(resource.RUSAGE_SELF)
cpu0 = ru0.ru_utime + ru0.ru_stime
t0 = time.perf_counter()
r = slam.run_log(__import__("pathlib").Path(log), cfg, __import__("pathlib").Path(out_dir), method=method)
wall = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
ru = resource.getrusage(resource.RUSAGE_SELF)
cpu = ru.ru_utime + ru.ru_stime - cpu0
vals = {m.name: m.value for m in r.metrics}
heavy_after = sorted({m.split(".")[0] for m in sys.modules} & set(heavy))
print(json.dumps({"wall_s": wall, "cpu_s": cpu, "bare_mb": bare, "after_imports_mb": after_imports, "peak_mb": peak,
                  "samples": samples, "metrics": vals, "mapping_rate": r.extra.get("mapping_rate"),
                  "heavy_before": heavy_before, "heavy_after": heavy_after}))
"""


@pytest.fixture(scope="module")
def bench_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    given = os.environ.get("MRNC_BENCH_SLAM_LOG")
    if given:
        return Path(given)
    from mrnc_eval.recording.recorder import SimRequest, simulate_log

    seconds = float(os.environ.get("MRNC_BENCH_SLAM_SECONDS", "30"))
    return simulate_log(tmp_path_factory.mktemp("bench") / f"forest{seconds:.0f}.mcap", Config(),
                        SimRequest(scene="forest", path="loop", duration_s=seconds, lidar="os0-128", columns=1024,
                                   seed=0, profile="field"))


def _run(log: Path, out: Path, method: str, interval: float, threads: int = 0) -> dict:
    load = os.getloadavg()[0]
    proc = subprocess.run([sys.executable, "-c", _RUN, str(log), str(out), method, str(interval),
                           json.dumps(RUN_IMPORTS[method]), json.dumps(HEAVY), str(threads)],
                          capture_output=True, text=True, check=False, env=os.environ.copy())
    assert proc.returncode == 0, proc.stderr[-2000:]
    out_ = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out_["heavy_after"] == out_["heavy_before"], "the run imported a heavy module the imports did not count"
    return {**out_, "load": load}


def _median_run(runs: list[dict]) -> dict:
    """The run with the median wall time (its CPU time, memory and metrics with it)."""
    return sorted(runs, key=lambda r: r["wall_s"])[len(runs) // 2]


def _growth_per_100_keyframes(samples: list[list[float]]) -> float:
    import numpy as np

    half = samples[len(samples) // 2:]
    if len(half) < 3:
        return float("nan")
    k, mb = np.asarray(half, float).T
    return float(np.polyfit(k, mb, 1)[0] * 100)


def _resident_mb_per_import(modules: tuple[str, ...]) -> dict[str, float]:
    """Resident MB a fresh interpreter adds by importing each module in turn ("bare": the interpreter)."""
    code = ("import importlib, json, resource, sys\n"
            "rss = lambda: int(open('/proc/self/statm').read().split()[1]) * resource.getpagesize() / 1e6\n"
            "prev = rss(); out = {'bare': prev}\n"
            "for m in sys.argv[1:]:\n"
            "    importlib.import_module(m); now = rss(); out[m] = now - prev; prev = now\n"
            "print(json.dumps(out))")
    proc = subprocess.run([sys.executable, "-c", code, *modules], capture_output=True, text=True, check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _kiss_icp_pipeline(folder: Path, cwd: Path) -> dict[str, float]:
    """kiss-icp's own command on the scans, in a child process: wall s, CPU s and peak resident MB."""
    exe = Path(sys.executable).with_name("kiss_icp_pipeline")
    code = ("import json, resource, subprocess, sys, time\nt = time.perf_counter()\n"
            "subprocess.run(sys.argv[1:], check=True, capture_output=True)\n"
            "ru = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
            "print(json.dumps({'wall_s': time.perf_counter() - t, 'cpu_s': ru.ru_utime + ru.ru_stime, "
            "'peak_mb': ru.ru_maxrss / 1e3}))")
    cwd.mkdir(parents=True, exist_ok=True)
    proc = subprocess.run([sys.executable, "-c", code, str(exe), str(folder)], capture_output=True, text=True,
                          check=True, cwd=cwd)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_slam_equal_work_speed_and_memory_vs_kiss_icp(bench_log: Path, tmp_path: Path) -> None:
    pytest.importorskip("kiss_icp", reason="kiss-icp extra not installed")
    print(f"\nload average before: {os.getloadavg()}")
    for method in ("lio", "kiss-icp"):  # warm-up: compile and cache outside the measurement
        _run(SAMPLE, tmp_path / f"warm-{method}", method, 0.15)
    rounds: dict[str, list[dict]] = {name: [] for name in RUNS}
    for k in range(REPEATS):  # alternating, so a change of the machine's load hits every row alike
        for i, (name, (method, interval, threads)) in enumerate(RUNS.items()):
            rounds[name].append(_run(bench_log, tmp_path / f"{k}-{i}", method, interval, threads))
    runs = {name: _median_run(rs) for name, rs in rounds.items()}
    loads = [r["load"] for rs in rounds.values() for r in rs]
    pipeline = _kiss_icp_pipeline(scans_folder(bench_log, tmp_path / "scans"), tmp_path / "kiss_out")
    per_import = _resident_mb_per_import(("numpy", *RUN_IMPORTS["lio"]))
    profile = "as recorded" if os.environ.get("MRNC_BENCH_SLAM_LOG") else "field sensor profile"
    print(f"{bench_log.name} ({bench_log.stat().st_size / 1e9:.2f} GB), {profile}; medians of {REPEATS} alternating "
          f"runs; load average (1 min) before the runs {min(loads):.2f}-{max(loads):.2f} on {os.cpu_count()} cores, "
          f"after: {os.getloadavg()}")
    print("resident MB added by each import of a lio run, in order: "
          + ", ".join(f"{k} {v:.0f}" for k, v in per_import.items()))
    print("| run | mapping rate | wall s (3 runs) | CPU s | RTF | APE online m | keyframes | imports MB | run holds MB "
          "| peak MB |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, r in runs.items():
        m = r["metrics"]
        walls = "/".join(f"{x['wall_s']:.1f}" for x in sorted(rounds[name], key=lambda x: x["wall_s"]))
        print(f"| {name} | {r['mapping_rate']} | {r['wall_s']:.1f} ({walls}) | {r['cpu_s']:.1f} | {m['rtf']:.2f} at "
              f"{m['mapping_rate_hz']:.1f} Hz | {m.get('ape_online_rmse_m', float('nan')):.4f} | {m['keyframes']} | "
              f"{r['after_imports_mb']:.0f} | {r['peak_mb'] - r['after_imports_mb']:.0f} | {r['peak_mb']:.0f} |")
    print(f"| kiss_icp_pipeline (its own command, .bin scans) | every sweep | {pipeline['wall_s']:.1f} | "
          f"{pipeline['cpu_s']:.1f} | - | - | - | - | - | {pipeline['peak_mb']:.0f} |")
    full, kiss = runs["lio @ every sweep"], runs["kiss-icp @ every sweep"]
    serial = runs["lio @ every sweep, --threads 1"]
    holds = full["peak_mb"] - full["after_imports_mb"]
    print(f"equal work (every sweep): lio {kiss['wall_s'] / full['wall_s']:.2f}x kiss-icp's speed in wall time, "
          f"{kiss['cpu_s'] / full['cpu_s']:.2f}x in CPU time (all threads); lio's peak {full['peak_mb']:.0f} MB = "
          f"{full['peak_mb'] / kiss['peak_mb']:.2f}x kiss-icp's in mrnc-eval ({kiss['peak_mb']:.0f} MB), "
          f"{full['peak_mb'] / pipeline['peak_mb']:.2f}x kiss_icp_pipeline's ({pipeline['peak_mb']:.0f} MB); "
          f"lio's run holds {holds:.0f} MB; two cores against one: {serial['wall_s'] / full['wall_s']:.2f}x in wall "
          "time")
    assert full["metrics"]["mapping_rate_hz"] > 9.0  # every sweep of a 10 Hz log
    assert full["metrics"]["ape_online_rmse_m"] == serial["metrics"]["ape_online_rmse_m"]  # same poses, any threads
    assert kiss["wall_s"] / full["wall_s"] >= MIN_WALL_RATIO
    assert full["metrics"]["ape_online_rmse_m"] < kiss["metrics"]["ape_online_rmse_m"]
    # memory, as ratios (the same reader and imports on both sides of the first pair)
    assert full["peak_mb"] <= 2.0 * kiss["peak_mb"]  # measured 1.52x (222 / 146 MB)
    assert holds < kiss["peak_mb"]  # measured 141 < 146 MB


def test_slam_memory_within_issue_30_targets_vs_kiss_icp_pipeline(bench_log: Path, tmp_path: Path) -> None:
    """Issue 30: peak (imports included) <= 2x kiss-icp's peak, and what the run holds beyond its
    imports below kiss-icp's peak; kiss-icp = its own kiss_icp_pipeline command, every sweep. Met since
    the SLAM's kernels are C (no numba, LLVM or scipy): lio 220-222 MB peak, run 139-141 MB, against the
    pipeline's 144-163 MB (main 87d110f, quiet machine)."""
    pytest.importorskip("kiss_icp", reason="kiss-icp extra not installed")
    _run(SAMPLE, tmp_path / "warm", "lio", 0.15)
    full = _run(bench_log, tmp_path / "lio", "lio", 0.0)
    pipeline = _kiss_icp_pipeline(scans_folder(bench_log, tmp_path / "scans"), tmp_path / "kiss_out")
    holds = full["peak_mb"] - full["after_imports_mb"]
    print(f"\nload average {os.getloadavg()}: lio peak {full['peak_mb']:.0f} MB (run holds {holds:.0f} MB), "
          f"kiss_icp_pipeline peak {pipeline['peak_mb']:.0f} MB")
    assert full["peak_mb"] <= 2.0 * pipeline["peak_mb"]
    assert holds < pipeline["peak_mb"]


@pytest.fixture(scope="module")
def growth_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    given = os.environ.get("MRNC_BENCH_SLAM_GROWTH_LOG")
    if given:
        return Path(given)
    from mrnc_eval.config import replace_path
    from mrnc_eval.recording.recorder import SimRequest, simulate_log

    cfg = replace_path(replace_path(replace_path(Config(), "sim.lidar.record_every", 10), "sim.path_size_m", 80.0),
                       "sim.scene_scale", 4.0)
    return simulate_log(tmp_path_factory.mktemp("growth") / "forest_loop80_os0-64_1hz_600s.mcap", cfg,
                        SimRequest(scene="forest", path="loop", duration_s=600, lidar="os0-64", columns=1024, seed=0,
                                   profile="ideal"))


def test_slam_memory_growth_per_100_keyframes(growth_log: Path, tmp_path: Path) -> None:
    """What the run holds per keyframe: every keyframe's feature clouds (float32) and its graph
    node stay for the whole run (loop closure and the final map need them); the map-frame cache
    holds only the current local map's keyframes."""
    _run(SAMPLE, tmp_path / "warm", "lio", 0.15)
    r = _run(growth_log, tmp_path / "run", "lio", 0.15)
    m, growth = r["metrics"], _growth_per_100_keyframes(r["samples"])
    given = os.environ.get("MRNC_BENCH_SLAM_GROWTH_LOG")
    profile = "as recorded" if given else "ideal sensor profile"
    print(f"\n{growth_log.name} ({growth_log.stat().st_size / 1e6:.0f} MB, {profile}): lio, {r['mapping_rate']}, "
          f"{m['keyframes']} keyframes, {m['loop_closures']} loop closures, APE online {m['ape_online_rmse_m']:.4f} m; "
          f"RTF {m['rtf']:.2f} at {m['mapping_rate_hz']:.1f} Hz; resident size {r['after_imports_mb']:.0f} MB after "
          f"imports, peak {r['peak_mb']:.0f} MB; growth {growth:.1f} MB per 100 keyframes (second half of the run)")
    assert m["keyframes"] >= 150, "the growth log must have well over 100 keyframes (the fit uses the second half)"
    assert growth < 60.0  # measured 29-30 MB per 100 keyframes (ideal profile, 195 keyframes, 167 loop closures)


def test_nearest_neighbour_backends_on_a_local_map() -> None:
    """Why the SLAM used pykdtree (slam/nearest.py; loop closure's ICP still does, scan-to-map searches its
    own tree since issue 30, slam/_match_kernels.c, 0.40 against pykdtree's 0.58 us a 5-NN query on forest30
    sweeps, the same neighbours): build + 5-NN query on a local map of the size
    LIO-SAM keeps (the voxelised clouds of 40 sweeps of the circle sample log, ~1e5 points;
    queries = one sweep's features), against scipy's cKDTree (2 workers) and open3d's KDTreeFlann."""
    import time

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
