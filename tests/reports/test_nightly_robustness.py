"""Nightly with the real pipelines: a real Dask cluster equals the local pool, SIGKILL and
re-run (both slow); a hostile log is escaped and contained (fast: it fails early or is only read)."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mrnc_eval.cli import main

from .test_nightly_executors import INFO, run_night

STABLE = ("slam/ape/ape_rmse_m", "slam/keyframes", "control/recorded/left/rms_error_mps",
          "control/recorded/path/cross_track_rms_m")


def _metrics(db: Path, night: str) -> dict[tuple[str, str], float]:
    with sqlite3.connect(db) as con:
        return {(log, m): v for log, m, v in con.execute(
            "SELECT log_id, metric, value FROM metrics WHERE night = ? AND value IS NOT NULL", (night,))}


@pytest.mark.slow
def test_dask_cluster_gives_the_same_metrics_as_the_local_pool(tiny_logs: Path, tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    local_root, dask_root = tmp_path / "local", tmp_path / "dask"
    assert main(["nightly", str(tiny_logs), "--out", str(local_root), "--jobs", "2", "--date", "2026-11-21",
                 "--no-pdf"]) in (0, 1)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address="127.0.0.1:0") as cluster:
        assert main(["nightly", str(tiny_logs), "--out", str(dask_root), "--scheduler", cluster.scheduler_address,
                     "--date", "2026-11-21", "--no-pdf"]) in (0, 1)
    a = _metrics(local_root / "history.sqlite", "2026-11-21")
    b = _metrics(dask_root / "history.sqlite", "2026-11-21")
    assert {k[0] for k in a} == {"a", "nested_b"}
    for part in ("slam", "control"):  # the results inside carry the night's id, not the file name's "b"
        inner = json.loads((local_root / "2026-11-21" / "logs" / "nested_b" / part / "result.json").read_text())
        assert inner["log_id"] == "nested_b", part
    assert [k for k in a if k[1] in STABLE]
    for key in [k for k in a if k[1] in STABLE]:
        assert b[key] == pytest.approx(a[key], rel=1e-9, abs=1e-12), key


@pytest.mark.slow
def test_killed_real_night_resumes_without_double_counting(tiny_logs: Path, tmp_path: Path) -> None:
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
        time.sleep(0.1)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    with sqlite3.connect(db) as con:
        first = con.execute("SELECT log_id, run_id FROM runs").fetchall()
    assert len(first) == 1
    assert main(["nightly", str(tiny_logs), "--out", str(root), "--jobs", "1", "--date", "2026-11-19",
                 "--no-pdf"]) in (0, 1)
    with sqlite3.connect(db) as con:
        assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        assert sorted(con.execute("SELECT log_id, status FROM runs").fetchall()) == [("a", "ok"), ("nested_b", "ok")]
        assert con.execute("SELECT log_id, run_id FROM runs WHERE log_id = ?", (first[0][0],)).fetchall() == first
        dup = con.execute("SELECT COUNT(*) FROM (SELECT night, log_id, metric FROM metrics GROUP BY 1, 2, 3 "
                          "HAVING COUNT(*) > 1)").fetchone()[0]
        assert dup == 0
    assert not list(root.rglob("*.partial"))


HOSTILE = '<script>alert("x")</script>'


def _hostile_logs(tmp_path: Path) -> Path:
    from mrnc_eval.io.writers import LogWriter

    logs = tmp_path / "logs"
    (logs / "sub<b>..").mkdir(parents=True)
    name = "evil<img src=x onerror=alert(1)>...mcap"
    with LogWriter(logs / "sub<b>.." / name, "mcap") as w:
        w.write_strings(f"/{HOSTILE}/../../etc", [1.0], [f"meta {HOSTILE} ../../../tmp/pwn"])
        w.write_strings("/ok", [1.0, 2.0], ["a", "b"])
    return logs


def _assert_contained(tmp_path: Path, root: Path, before: list[str]) -> None:
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(before + [root.name])
    for p in root.rglob("*"):
        assert root.resolve() in p.resolve().parents
        assert "<" not in p.name
        assert ">" not in p.name


def test_hostile_log_fails_cleanly_escaped_and_contained(tmp_path: Path) -> None:
    logs = _hostile_logs(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    root = tmp_path / "reports"
    rc = main(["nightly", str(logs), "--out", str(root), "--jobs", "1", "--date", "2026-11-18", "--no-pdf"])
    assert rc == 3  # no LiDAR: the log fails, clearly, and the night still writes its index
    index = (root / "2026-11-18" / "index.html").read_text(encoding="utf-8")
    assert "<script" not in index
    assert "<img" not in index
    assert "&lt;img src=x onerror=alert(1)&gt;" in index
    _assert_contained(tmp_path, root, before)


def test_hostile_topics_are_escaped_in_the_report(tmp_path: Path) -> None:
    logs = _hostile_logs(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    root = tmp_path / "reports"
    assert run_night(logs, root, night="2026-11-17", analysis=INFO) == 0
    (report,) = list((root / "2026-11-17" / "logs").glob("*/report.html"))
    page = report.read_text(encoding="utf-8")
    assert "&lt;script&gt;alert(&#34;x&#34;)&lt;/script&gt;" in page  # the topic name, shown as text
    assert "<script" not in page
    assert "<img" not in page
    assert "onerror=alert(1)>" not in page
    _assert_contained(tmp_path, root, before)
