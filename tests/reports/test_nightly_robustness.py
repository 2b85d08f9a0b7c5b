"""Nightly: Dask cluster equals the local pool; SIGKILL and re-run; hostile logs."""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mrnc_eval.cli import main

STABLE = ("slam/ape/ape_rmse_m", "slam/slam/keyframes", "control/recorded/left/rms_error_mps",
          "control/recorded/path/cross_track_rms_m")


def _metrics(db: Path, night: str) -> dict[tuple[str, str], float]:
    with sqlite3.connect(db) as con:
        return {(log, m): v for log, m, v in con.execute(
            "SELECT log_id, metric, value FROM metrics WHERE night = ? AND value IS NOT NULL", (night,))}


def test_dask_cluster_gives_the_same_metrics_as_the_local_pool(tiny_logs: Path, tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    local_root, dask_root = tmp_path / "local", tmp_path / "dask"
    assert main(["nightly", str(tiny_logs), "--out", str(local_root), "--jobs", "2", "--date", "2026-11-21",
                 "--no-pdf"]) in (0, 1)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        assert main(["nightly", str(tiny_logs), "--out", str(dask_root), "--scheduler", cluster.scheduler_address,
                     "--date", "2026-11-21", "--no-pdf"]) in (0, 1)
    a = _metrics(local_root / "history.sqlite", "2026-11-21")
    b = _metrics(dask_root / "history.sqlite", "2026-11-21")
    assert {k[0] for k in a} == {"a", "b", "c"}
    for key in [k for k in a if k[1] in STABLE]:
        assert b[key] == pytest.approx(a[key], rel=1e-9, abs=1e-12), key


def test_killed_night_resumes_without_double_counting(tiny_logs: Path, tmp_path: Path) -> None:
    root = tmp_path / "night"
    db = root / "history.sqlite"
    cmd = [sys.executable, "-m", "mrnc_eval", "nightly", str(tiny_logs), "--out", str(root), "--jobs", "1",
           "--date", "2026-11-19", "--no-pdf"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.time() + 300
    while time.time() < deadline:  # kill as soon as the first log is in the history
        if db.exists():
            try:
                with sqlite3.connect(db) as con:
                    if con.execute("SELECT COUNT(*) FROM runs").fetchone()[0] >= 1:
                        break
            except sqlite3.OperationalError:
                pass
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    with sqlite3.connect(db) as con:
        done_before = con.execute("SELECT COUNT(*) FROM runs").fetchone()[0]
    assert 1 <= done_before < 3
    assert main(["nightly", str(tiny_logs), "--out", str(root), "--jobs", "1", "--date", "2026-11-19",
                 "--no-pdf"]) in (0, 1)
    with sqlite3.connect(db) as con:
        assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        runs = con.execute("SELECT log_id, status FROM runs WHERE night = '2026-11-19'").fetchall()
        assert sorted(runs) == [("a", "ok"), ("b", "ok"), ("c", "ok")]
        per_log = dict(con.execute("SELECT log_id, COUNT(*) FROM metrics GROUP BY log_id").fetchall())
        dup = con.execute("SELECT COUNT(*) FROM (SELECT night, log_id, metric FROM metrics GROUP BY 1, 2, 3 "
                          "HAVING COUNT(*) > 1)").fetchone()[0]
    assert dup == 0 and len(set(per_log.values())) <= 2  # every log has its full metric set once
    assert not list((root / "2026-11-19" / "logs").glob(".*partial"))
    # a re-run of the same night is idempotent and never touches another night
    before = _metrics(db, "2026-11-19")
    assert main(["nightly", str(tiny_logs), "--out", str(root), "--jobs", "1", "--date", "2026-11-19",
                 "--no-pdf"]) in (0, 1)
    assert _metrics(db, "2026-11-19") == before


def test_hostile_log_is_escaped_and_contained(tmp_path: Path) -> None:
    from mrnc_eval.io.writers import LogWriter

    logs = tmp_path / "logs"
    logs.mkdir()
    hostile = '<script>alert("x")</script>'
    name = "..evil<img src=x onerror=alert(1)>.mcap"
    w = LogWriter(logs / name, "mcap")
    w.write_strings(f"/{hostile}/../../etc", [1.0], [f"meta {hostile} ../../../tmp/pwn"])
    w.write_strings("/ok", [1.0, 2.0], ["a", "b"])
    w.close()
    outside_before = sorted(p.name for p in tmp_path.iterdir())
    root = tmp_path / "reports"
    rc = main(["nightly", str(logs), "--out", str(root), "--jobs", "1", "--date", "2026-11-18", "--no-pdf"])
    assert rc == 3  # no LiDAR: the log fails, clearly
    index = (root / "2026-11-18" / "index.html").read_text(encoding="utf-8")
    assert "<script" not in index and "<img" not in index  # only escaped text reaches the page
    assert "&lt;img src=x onerror=alert(1)&gt;" in index
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(outside_before + ["reports"])
    for p in root.rglob("*"):
        assert root in p.resolve().parents or p.resolve() == root
