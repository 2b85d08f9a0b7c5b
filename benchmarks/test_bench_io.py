"""Log reading: sweep decoding speed on the real OS1-128 recording against rosbags' own
deserialiser as the peer, and bounded memory while streaming a generated 200-sweep log.

Run: .venv/bin/python -m pytest -m benchmark benchmarks/test_bench_io.py -s
"""

from __future__ import annotations

import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.io import open_log
from mrnc_eval.io.writers import LogWriter

pytestmark = pytest.mark.benchmark

REPEATS = 10
REAL_OUSTER = (Path(__file__).resolve().parents[2] / "shared" / "data" / "ouster-os1-128-real-3scans"
               / "ouster_real_ros2_mcap_zstd.mcap")


@pytest.fixture
def real_ouster_mcap() -> Path:
    if not REAL_OUSTER.exists():
        pytest.skip(f"real Ouster recording not found at {REAL_OUSTER}")
    return REAL_OUSTER


def _ours(path: Path) -> tuple[int, int]:
    n = pts = 0
    with open_log(path) as log:
        for s in log.sweeps():
            n += 1
            pts += len(s)
    return n, pts


def _peer_rosbags(path: Path) -> tuple[int, int]:
    """rosbags AnyReader + deserialize_cdr + a structured numpy view of x/y/z: the least any
    reader must do to hand out points (no time normalisation, no no-return removal)."""
    from rosbags.highlevel import AnyReader

    n = pts = 0
    with AnyReader([path]) as reader:
        conns = [c for c in reader.connections if c.topic == "/ouster/points"]
        for conn, _t, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            dt = np.dtype({"names": ["x", "y", "z"], "formats": ["<f4"] * 3, "offsets": [0, 4, 8],
                           "itemsize": msg.point_step})
            arr = np.frombuffer(msg.data, dtype=dt)
            xyz = np.stack([arr["x"], arr["y"], arr["z"]], axis=1)
            n += 1
            pts += int(np.count_nonzero(np.abs(xyz).sum(axis=1) > 0))
    return n, pts


def _rate(fn, path: Path) -> tuple[float, tuple[int, int]]:
    fn(path)  # warm caches and imports
    t0 = time.perf_counter()
    for _ in range(REPEATS):
        out = fn(path)
    return out[0] * REPEATS / (time.perf_counter() - t0), out


def test_real_recording_sweeps_per_second(real_ouster_mcap: Path) -> None:
    ours, (n, pts) = _rate(_ours, real_ouster_mcap)
    peer, (n_peer, pts_peer) = _rate(_peer_rosbags, real_ouster_mcap)
    print(f"\nreal OS1-128 (3 sweeps, {pts // n} returns/sweep): ours {ours:.1f} sweeps/s, "
          f"rosbags deserialise+xyz view {peer:.1f} sweeps/s, ratio {ours / peer:.2f}")
    assert (n, pts) == (n_peer, pts_peer) == (3, pts)
    assert ours > 0.5 * peer  # full decoding (time, ring, column, removal) within 2x of the bare minimum


def _write_long_log(path: Path, fmt: str, n_sweeps: int, h: int, w: int) -> int:
    rng = np.random.default_rng(0)
    t_ns = np.repeat((np.arange(w, dtype=np.uint32) * (100_000_000 // w))[None, :], h, axis=0)
    with LogWriter(path, fmt) as lw:
        for k in range(n_sweeps):
            xyz = rng.normal(scale=10.0, size=(h, w, 3)).astype(np.float32)
            r = (np.linalg.norm(xyz, axis=2) * 1000).astype(np.uint32)
            z16 = np.zeros((h, w), np.uint16)
            lw.write_ouster_cloud("/ouster/points", 10.0 + 0.1 * k, xyz, t_ns, r, z16, z16.astype(np.float32), z16)
    return h * w * 48


@pytest.mark.parametrize(("fmt", "name"), [("mcap", "long.mcap"), ("db3", "long.db3"), ("bag", "long.bag")])
def test_streaming_memory_is_bounded(tmp_path: Path, fmt: str, name: str) -> None:
    n_sweeps, h, w = 200, 32, 1024
    sweep_bytes = _write_long_log(tmp_path / name, fmt, n_sweeps, h, w)
    with open_log(tmp_path / name) as log:
        log.topics  # noqa: B018 - the index scan is part of opening a log for use
        tracemalloc.start()
        n = 0
        for s in log.sweeps():
            n += 1
            assert len(s) == h * w
        _cur, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
    total = sweep_bytes * n_sweeps
    print(f"\n{fmt}: {n} sweeps of {sweep_bytes / 1e6:.2f} MB ({total / 1e6:.0f} MB in all), "
          f"tracemalloc peak while streaming {peak / 1e6:.1f} MB = {peak / sweep_bytes:.1f} sweeps")
    assert n == n_sweeps
    assert peak < 12 * sweep_bytes  # a few sweeps plus one container chunk, never the whole log


def test_imu_batched_vs_per_message(tmp_path: Path) -> None:
    """60,000 IMU messages (10 min at 100 Hz): batched byte decoding vs rosbags' deserialiser."""
    from mrnc_eval.data import ImuSeries

    n = 60_000
    rng = np.random.default_rng(0)
    imu = ImuSeries(100 + np.arange(n) * 0.01, rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), None, "os_imu")
    for fmt, name in (("mcap", "imu.mcap"), ("bag", "imu.bag")):
        with LogWriter(tmp_path / name, fmt) as w:
            w.write_imu("/ouster/imu", imu)
        times = {}
        for fast in (True, False):
            with open_log(tmp_path / name) as log:
                t0 = time.perf_counter()
                got = log.imu(fast=fast)
                times[fast] = time.perf_counter() - t0
            np.testing.assert_array_equal(got.acc, imu.acc)
        print(f"\n{fmt}: imu() {n} messages: batched {times[True]:.2f} s, per message {times[False]:.2f} s, "
              f"speed-up {times[False] / times[True]:.1f}x")
        assert times[True] < times[False]
