"""Nightly mechanics with a light injected analysis (real log reading and report rendering):
discovery, executors (in-process, spawned pool, real Dask cluster), native-crash isolation,
SIGKILL + resume, idempotent re-runs, history, regressions."""

from __future__ import annotations

import datetime as dt
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mrnc_eval.commands import nightly
from mrnc_eval.config import Config
from mrnc_eval.errors import GateFailed, SomeInputsFailed
from mrnc_eval.history import find_regressions

from .nightly_workers import CALLS_ENV, SLEEP_ENV

INFO = "tests.reports.nightly_workers:info_analysis"
CRASHING = "tests.reports.nightly_workers:crashing_analysis"
IDS = ["l1", "l2", "night_deeper_l4", "night_l3", "night_l5"]


def run_night(logs: Path, out: Path, *, night: str, jobs: int = 1, scheduler: str | None = None,
              analysis: str = INFO, gates: Path | None = None) -> int:
    """nightly.main as the CLI maps it: 0, 1 (GateFailed) or 3 (SomeInputsFailed)."""
    try:
        nightly.main(logs, Config(), out=out, jobs=jobs, scheduler=scheduler, since=None, gates=gates, date=night,
                     pdf=False, analysis=analysis)
    except SomeInputsFailed:
        return 3
    except GateFailed:
        return 1
    return 0


def metrics(db: Path, night: str) -> dict[tuple[str, str], float]:
    with sqlite3.connect(db) as con:
        return {(log, m): v for log, m, v in con.execute(
            "SELECT log_id, metric, value FROM metrics WHERE night = ? AND value IS NOT NULL", (night,))}


def test_discovery_finds_every_container_recursively_and_skips_ground_truth(imu_logs: Path) -> None:
    found = nightly.discover_logs(imu_logs)
    rel = sorted(str(p.relative_to(imu_logs)) for p in found)
    assert rel == ["l1.mcap", "l2.bag", "night/deeper/l4.mcap", "night/l3.mcap", "night/l5"]
    assert nightly.discover_logs(imu_logs, dt.date(2999, 1, 1)) == []
    ids = nightly._unique_ids(found, imu_logs)
    assert sorted(ids.values()) == IDS


def test_in_process_pool_and_dask_cluster_give_the_same_history(imu_logs: Path, tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    night = "2026-11-01"
    assert run_night(imu_logs, tmp_path / "inproc", night=night, jobs=1) == 0
    assert run_night(imu_logs, tmp_path / "pool", night=night, jobs=2) == 0
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address="127.0.0.1:0") as cluster:
        workers = cluster.scheduler_info["workers"]
        assert len(workers) == 2
        assert all(addr.startswith("tcp://127.0.0.1:") for addr in workers)
        assert run_night(imu_logs, tmp_path / "dask", night=night, scheduler=cluster.scheduler_address) == 0
    reference = metrics(tmp_path / "inproc" / "history.sqlite", night)
    assert {log for log, _ in reference} == set(IDS)
    assert reference[("l1", "info/messages")] == 50
    assert reference[("night_l3", "info/messages")] == 120
    assert reference[("night_l3", "info/duration_s")] == pytest.approx(1.19)  # 120 samples at 100 Hz
    # each night records how many logs ran at once (1, 2, 0 for a cluster); every measured value is the same
    concurrency = {"inproc": 1.0, "pool": 2.0, "dask": 0.0}
    assert {v for (_, m), v in reference.items() if m == nightly.CONCURRENCY_METRIC} == {concurrency["inproc"]}
    for other in ("pool", "dask"):
        theirs = metrics(tmp_path / other / "history.sqlite", night)
        assert {v for (_, m), v in theirs.items() if m == nightly.CONCURRENCY_METRIC} == {concurrency[other]}
        measured = {k: v for k, v in theirs.items() if k[1] != nightly.CONCURRENCY_METRIC}
        assert measured == {k: v for k, v in reference.items() if k[1] != nightly.CONCURRENCY_METRIC}, other
        index = (tmp_path / other / night / "index.html").read_text(encoding="utf-8")
        assert all(f'href="logs/{log}/report.html"' in index for log in IDS)


def test_a_native_crash_fails_only_its_own_log(imu_logs: Path, tmp_path: Path) -> None:
    from .conftest import write_imu_log

    logs = tmp_path / "logs"
    logs.mkdir()
    for name in ("a", "b_crash", "c", "d"):
        write_imu_log(logs / f"{name}.mcap", 40)
    out = tmp_path / "out"
    assert run_night(logs, out, night="2026-11-02", jobs=2, analysis=CRASHING) == 3
    with sqlite3.connect(out / "history.sqlite") as con:
        rows = dict(con.execute("SELECT log_id, status FROM runs").fetchall())
        error = con.execute("SELECT error FROM runs WHERE log_id = 'b_crash'").fetchone()[0]
    assert rows == {"a": "ok", "b_crash": "failed", "c": "ok", "d": "ok"}
    assert "worker process died" in error
    index = (out / "2026-11-02" / "index.html").read_text(encoding="utf-8")
    assert "worker process died" in index
    assert 'href="logs/c/report.html"' in index


def test_killed_night_resumes_without_redoing_or_double_counting(imu_logs: Path, tmp_path: Path) -> None:
    out, calls = tmp_path / "out", tmp_path / "calls"
    calls.mkdir()
    db = out / "history.sqlite"
    code = ("import sys; from pathlib import Path; from mrnc_eval.config import Config; "
            "from mrnc_eval.commands import nightly; "
            f"nightly.main(Path({str(imu_logs)!r}), Config(), out=Path({str(out)!r}), jobs=1, scheduler=None, "
            f"since=None, gates=None, date='2026-11-03', pdf=False, analysis={INFO!r})")
    env = {**os.environ, CALLS_ENV: str(calls), SLEEP_ENV: "0.4",
           "PYTHONPATH": os.pathsep.join([str(Path(__file__).parents[2]), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, start_new_session=True)
    deadline = time.time() + 120
    done = 0
    while time.time() < deadline and proc.poll() is None:
        if db.exists():
            try:
                with sqlite3.connect(db) as con:
                    done = con.execute("SELECT COUNT(*) FROM runs").fetchone()[0]
            except sqlite3.OperationalError:
                pass
        if done >= 2:
            break
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert 2 <= done < 5, proc.stderr.read().decode()[-2000:]
    finished_before = {p.name.split(".")[0] for p in calls.iterdir()}
    with sqlite3.connect(db) as con:
        done_before = {r[0] for r in con.execute("SELECT log_id FROM runs")}
    os.environ[CALLS_ENV] = str(calls)
    try:
        assert run_night(imu_logs, out, night="2026-11-03") == 0
        per_log: dict[str, int] = {}
        for p in calls.iterdir():
            per_log[p.name.split(".")[0]] = per_log.get(p.name.split(".")[0], 0) + 1
        assert sorted(per_log) == IDS
        assert all(per_log[log] == 1 for log in done_before)  # finished logs were not redone
        assert sum(per_log.values()) <= len(IDS) + 1  # at most the log in flight at the kill ran twice
        assert done_before <= finished_before
        with sqlite3.connect(db) as con:
            assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
            assert sorted(con.execute("SELECT log_id, status FROM runs WHERE night = '2026-11-03'").fetchall()) == \
                [(log, "ok") for log in IDS]
            counts = con.execute("SELECT log_id, COUNT(*) FROM metrics GROUP BY log_id").fetchall()
        assert sorted(counts) == [(log, 5) for log in IDS]  # 3 metrics, gates_failed, concurrency: each once
        assert not list(out.rglob("*.partial"))
        assert not list(out.rglob(".*.tmp"))
        # a re-run of the same night is idempotent: nothing redone, history unchanged
        before = metrics(db, "2026-11-03")
        n_calls = len(list(calls.iterdir()))
        assert run_night(imu_logs, out, night="2026-11-03") == 0
        assert metrics(db, "2026-11-03") == before
        assert len(list(calls.iterdir())) == n_calls
    finally:
        del os.environ[CALLS_ENV]


def test_later_nights_leave_earlier_ones_untouched_and_flag_regressions(imu_logs: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    gates = tmp_path / "gates.yaml"
    gates.write_text("ape_rmse_max_m: 0.05\n", encoding="utf-8")
    assert run_night(imu_logs, out, night="2026-11-04", gates=gates) == 0
    with sqlite3.connect(out / "history.sqlite") as con:
        first = con.execute("SELECT * FROM metrics WHERE night = '2026-11-04' ORDER BY log_id, metric").fetchall()
    assert run_night(imu_logs, out, night="2026-11-05") == 0
    with sqlite3.connect(out / "history.sqlite") as con:
        again = con.execute("SELECT * FROM metrics WHERE night = '2026-11-04' ORDER BY log_id, metric").fetchall()
        assert con.execute("SELECT COUNT(DISTINCT night) FROM runs").fetchone()[0] == 2
    assert again == first
    trends = (out / "trends.html").read_text(encoding="utf-8")
    assert 'href="2026-11-04/index.html"' in trends
    assert 'href="2026-11-05/index.html"' in trends


def test_regression_flags_against_the_median_of_previous_nights() -> None:
    per_log = {"a": {"n1": 0.10, "n2": 0.11, "n3": 0.09, "n4": 0.13},  # +30 % over the median 0.10
               "b": {"n1": 0.10, "n2": 0.10, "n3": 0.11},  # +10 %: within tolerance
               "c": {"n1": 0.0, "n2": 0.0, "n3": 1.0}}  # from zero: any increase counts
    flagged = find_regressions("m", per_log, window=5, tolerance=0.2)
    assert [(f.log_id, f.night, f.value, f.reference) for f in flagged] == [("a", "n4", 0.13, 0.10),
                                                                             ("c", "n3", 1.0, 0.0)]
    assert find_regressions("rtf", {"a": {"n1": 2.0, "n2": 1.5}}, 5, 0.2, higher_is_better=True)
    assert not find_regressions("rtf", {"a": {"n1": 2.0, "n2": 1.9}}, 5, 0.2, higher_is_better=True)
    # only the previous `window` nights count
    assert not find_regressions("m", {"a": {"n1": 10.0, "n2": 1.0, "n3": 1.0, "n4": 1.1}}, 2, 0.2)


def test_trends_page_flags_a_regressed_log(tmp_path: Path) -> None:
    from mrnc_eval.history import History, LogRecord

    history = History(tmp_path / "history.sqlite")
    ape = {"2026-10-01": 0.05, "2026-10-02": 0.05, "2026-10-03": 0.09}
    for night, value in ape.items():
        for log_id, v in (("steady", 0.05), ("<b>worse</b>", value)):
            history.record(LogRecord(night, log_id, "r", "p", "0", "c", "ok", "", "t",
                                     (("slam/ape/ape_rmse_m", v, "m"), ("slam/rtf", 2.0, ""))))
    regressions = nightly._write_trends(history, tmp_path)
    assert [(r.log_id, r.metric, r.night) for r in regressions] == [("<b>worse</b>", "slam/ape/ape_rmse_m",
                                                                     "2026-10-03")]
    page = (tmp_path / "trends.html").read_text(encoding="utf-8")
    assert "&lt;b&gt;worse&lt;/b&gt;: slam/ape/ape_rmse_m = 0.09 on 2026-10-03" in page
    assert "<b>" not in page
    assert page.count("<figure>") == 2  # APE RMSE and RTF


def test_a_second_nightly_on_the_same_root_is_refused(imu_logs: Path, tmp_path: Path) -> None:
    import fcntl

    from mrnc_eval.errors import UsageError

    out = tmp_path / "out"
    out.mkdir()
    with open(out / ".nightly.lock", "a+b") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        with pytest.raises(UsageError, match="another nightly"):
            run_night(imu_logs, out, night="2026-11-06")
    assert not (out / "history.sqlite").exists()
    assert run_night(imu_logs, out, night="2026-11-06") == 0  # released: runs
    assert not (out / ".nightly.lock").exists()  # removed after the run, not left in the report root


def test_a_failed_gate_exits_1_and_is_named_in_the_index_and_history(imu_logs: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert run_night(imu_logs, out, night="2026-11-07", analysis="tests.reports.nightly_workers:gated_analysis") == 1
    index = (out / "2026-11-07" / "index.html").read_text(encoding="utf-8")
    assert index.count("fail: APE RMSE") == 1
    assert index.count(">pass</td>") == len(IDS) - 1
    with sqlite3.connect(out / "history.sqlite") as con:
        assert con.execute("SELECT log_id FROM metrics WHERE metric = 'gate_failed/APE RMSE'").fetchall() == [("l1",)]


def test_gate_cards_judge_the_worst_deployed_value() -> None:
    from mrnc_eval.evaluation.config import GatesConfig
    from mrnc_eval.reports.render import evaluate_gates
    from mrnc_eval.results import Metric, RunResult

    slam = RunResult(kind="slam", log_path="x.mcap", log_id="x",
                     metrics=[Metric(name="ape_rmse_m", value=0.12, unit="m", group="slam/ape")])
    control = RunResult(kind="control", log_path="x.mcap", log_id="x", metrics=[
        Metric(name="funnel_violations", value=0, unit="", group="control/raid/left"),
        Metric(name="funnel_violations", value=3, unit="", group="control/pid/left"),
        Metric(name="saturation_ratio", value=0.1, unit="", group="control/raid/left"),
        Metric(name="saturation_ratio", value=0.3, unit="", group="control/raid/right"),
        Metric(name="safety_stops", value=float("nan"), unit="", group="control/raid/left")])
    cards = {g.label: (g.value, g.status) for g in evaluate_gates([slam, control], GatesConfig())}
    assert cards == {"APE RMSE": ("0.120 m", "fail"), "Funnel violations": ("0", "pass"),  # PID is not gated
                     "Saturation ratio": ("0.300", "fail"),
                     "Safety stops": ("not a finite number: nan", "fail")}  # a NaN never skips (issue 26)
