"""History of per-log metrics across nights, in SQLite (stdlib, one file, WAL, transactions).

Why SQLite: no server, safe concurrent readers, atomic transactions so a killed night never
leaves half a log's metrics behind, and it ships with Python. Each (night, log) is written in
one transaction after its results are complete; re-running a night replaces that night's
rows only (idempotent); earlier nights are never touched."""

from __future__ import annotations

import contextlib
import sqlite3
import statistics
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, NamedTuple

from mrnc_eval.errors import InputError, OutputError

HISTORY_FILE = "history.sqlite"  # in a nightly report root

SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
  night TEXT NOT NULL, log_id TEXT NOT NULL, run_id TEXT NOT NULL, log_path TEXT NOT NULL,
  tool_version TEXT NOT NULL, config_hash TEXT NOT NULL, status TEXT NOT NULL, error TEXT NOT NULL,
  finished_utc TEXT NOT NULL, log_stamp TEXT NOT NULL DEFAULT '', PRIMARY KEY (night, log_id));
CREATE TABLE IF NOT EXISTS metrics (
  night TEXT NOT NULL, log_id TEXT NOT NULL, run_id TEXT NOT NULL, tool_version TEXT NOT NULL,
  config_hash TEXT NOT NULL, metric TEXT NOT NULL, value REAL, unit TEXT NOT NULL, status TEXT NOT NULL,
  PRIMARY KEY (night, log_id, metric));
"""

METRIC_ROW_COLUMNS = ("night", "log_id", "metric", "value", "unit", "status", "config_hash")
RunStatus = Literal["ok", "failed"]  # a log's outcome in a night


class MetricRow(NamedTuple):
    """One stored metric, in METRIC_ROW_COLUMNS' order (a tuple, so a DataFrame takes it as a row)."""

    night: str
    log_id: str
    metric: str
    value: float | None
    unit: str
    status: RunStatus
    config_hash: str


@dataclass(frozen=True)
class LogRecord:
    night: str
    log_id: str
    run_id: str
    log_path: str
    tool_version: str
    config_hash: str
    status: RunStatus
    error: str
    finished_utc: str
    metrics: tuple[tuple[str, float | None, str], ...]  # (name, value, unit)
    log_stamp: str = ""  # size and modification time of the log: a changed log is processed again


@dataclass(frozen=True)
class LastRun:
    night: str
    status: RunStatus
    config_hash: str
    log_stamp: str


class History:
    def __init__(self, path: Path) -> None:
        self.path = path
        path.parent.mkdir(parents=True, exist_ok=True)
        try:
            with closing(self._connect()) as db:
                db.executescript(SCHEMA)
                columns = {row[1] for row in db.execute("PRAGMA table_info(runs)")}
                if "log_stamp" not in columns:  # a history written before log stamps were kept
                    db.execute("ALTER TABLE runs ADD COLUMN log_stamp TEXT NOT NULL DEFAULT ''")
        except sqlite3.DatabaseError as err:
            raise _damaged(path, err) from err

    def _query(self, sql: str, args: tuple[Any, ...] = ()) -> list[Any]:
        """Rows of a read; a damaged database file is an InputError naming it (not a bug)."""
        try:
            with closing(self._connect()) as db:
                return list(db.execute(sql, args))
        except sqlite3.DatabaseError as err:
            raise _damaged(self.path, err) from err

    def _connect(self) -> sqlite3.Connection:
        db = sqlite3.connect(self.path, timeout=30.0, isolation_level=None)
        db.execute("PRAGMA journal_mode=WAL")
        db.execute("PRAGMA synchronous=FULL")
        return db

    def record(self, rec: LogRecord) -> None:
        """Replace this night's rows of this log, all in one transaction; a failed write (disk
        full, read-only) is an OutputError naming the history file, earlier rows untouched."""
        try:
            self._record(rec)
        except sqlite3.Error as err:
            raise OutputError(self.path, f"cannot write the history: {err}") from err

    def _record(self, rec: LogRecord) -> None:
        with closing(self._connect()) as db:
            db.execute("BEGIN IMMEDIATE")
            try:
                db.execute("DELETE FROM metrics WHERE night = ? AND log_id = ?", (rec.night, rec.log_id))
                db.execute("INSERT OR REPLACE INTO runs VALUES (?,?,?,?,?,?,?,?,?,?)",
                           (rec.night, rec.log_id, rec.run_id, rec.log_path, rec.tool_version, rec.config_hash,
                            rec.status, rec.error, rec.finished_utc, rec.log_stamp))
                db.executemany("INSERT INTO metrics VALUES (?,?,?,?,?,?,?,?,?)",
                               [(rec.night, rec.log_id, rec.run_id, rec.tool_version, rec.config_hash, name, value,
                                 unit, rec.status) for name, value, unit in rec.metrics])
                db.execute("COMMIT")
            except BaseException:
                with contextlib.suppress(sqlite3.Error):  # SQLite may have rolled back already (disk full):
                    db.execute("ROLLBACK")  # the error to surface is the first one, not "cannot rollback"
                raise

    def last_runs(self) -> dict[str, LastRun]:
        """log_id -> its most recently finished run, any night, any status."""
        rows = self._query("SELECT log_id, night, status, config_hash, log_stamp FROM runs "
                           "ORDER BY finished_utc, night")
        return {log_id: LastRun(night, status, cfg, stamp) for log_id, night, status, cfg, stamp in rows}

    def runs(self, night: str) -> list[tuple[str, RunStatus, str, str]]:  # (log_id, status, error, log_path)
        return self._query("SELECT log_id, status, error, log_path FROM runs WHERE night = ? ORDER BY log_id",
                           (night,))

    def metric_series(self, night: str | None = None) -> list[tuple[str, str, str, float]]:
        """(night, log_id, metric, value) of successful runs (of one night if given), ordered by night."""
        where = "status = 'ok' AND value IS NOT NULL" + (" AND night = ?" if night else "")
        return self._query(f"SELECT night, log_id, metric, value FROM metrics WHERE {where} "
                           "ORDER BY night, log_id, metric", (night,) if night else ())

    def metric_rows(self, night: str | None = None) -> list[MetricRow]:
        """Every stored metric (of one night if given) as METRIC_ROW_COLUMNS, ordered by night, log, metric."""
        where = " WHERE night = ?" if night else ""
        return [MetricRow(*row) for row in self._query(f"SELECT {', '.join(METRIC_ROW_COLUMNS)} FROM metrics{where} "
                           "ORDER BY night, log_id, metric", (night,) if night else ())]

    def nights(self) -> list[str]:
        return [r[0] for r in self._query("SELECT DISTINCT night FROM runs ORDER BY night")]


def _damaged(path: Path, err: sqlite3.DatabaseError) -> InputError:
    return InputError(path, f"damaged history database ({err}); move it aside to start a new history")


def open_history(root: Path) -> History:
    """The history of the report root `root`, which must exist (reading never creates one)."""
    path = root / HISTORY_FILE
    if not path.is_file():
        raise InputError(path, "no nightly history here (history.sqlite)")
    return History(path)


@dataclass(frozen=True)
class Regression:
    metric: str
    log_id: str
    night: str
    value: float
    reference: float  # median of the previous nights
    nights_compared: int

    def __str__(self) -> str:
        return (f"{self.log_id}: {self.metric} = {self.value:.4g} on {self.night}, median of the previous "
                f"{self.nights_compared} nights {self.reference:.4g}")


def find_regressions(metric: str, per_log: dict[str, dict[str, float]], window: int, tolerance: float, *,
                     higher_is_better: bool = False) -> list[Regression]:
    """Logs whose latest value of `metric` is worse than the median of their previous `window`
    nights by more than `tolerance` (relative; any increase counts when that median is 0)."""
    out = []
    for log_id, by_night in sorted(per_log.items()):
        nights = sorted(by_night)
        if len(nights) < 2:
            continue
        last, prev = by_night[nights[-1]], [by_night[n] for n in nights[:-1][-window:]]
        ref = statistics.median(prev)
        worse = last < ref * (1 - tolerance) if higher_is_better else last > ref * (1 + tolerance) + 1e-12
        if worse:
            out.append(Regression(metric, log_id, nights[-1], last, ref, len(prev)))
    return out
