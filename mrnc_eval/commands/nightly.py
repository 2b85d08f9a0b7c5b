"""`mrnc-eval nightly`: every new log of a folder -> SLAM + control + report, a night index,
trends across nights, and a metrics history. Safe to run unattended: per-log outputs are
moved into place when complete, history is written per log in one transaction, a killed night
resumes where it stopped, earlier nights are never modified."""

from __future__ import annotations

import datetime as dt
import logging
import re
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from mrnc_eval.commands.log_job import DEFAULT_ANALYSIS, LogJob, LogSummary
from mrnc_eval.commands.progress import progress_bar
from mrnc_eval.config import Config, as_dict, build, config_hash, dump_config, load_yaml_file
from mrnc_eval.errors import ConfigError, GateFailed, InputError, SomeInputsFailed, UsageError
from mrnc_eval.history import History, LastRun, LogRecord, Regression, find_regressions
from mrnc_eval.io.containers import LOG_SUFFIXES
from mrnc_eval.reports.night import IndexRow
from mrnc_eval.results import atomic_write_text, check_output_root, link_latest, path_hash, stable_id
from mrnc_eval.text import shorten

if TYPE_CHECKING:
    from mrnc_eval.commands.executors import Executor

log = logging.getLogger(__name__)
MAPPING_RATE_METRIC = "slam/mapping_rate_hz"  # the work an RTF was measured at, charted beside it
TREND_METRICS = ("slam/ape/ape_rmse_m", "slam/ape/end_drift_m", "slam/rtf", MAPPING_RATE_METRIC,
                 "control/recorded/left/rms_error_mps",
                 "control/recorded/right/rms_error_mps", "control/recorded/left/funnel_violations",
                 "control/recorded/right/funnel_violations", "control/recorded/path/cross_track_rms_m")
HIGHER_IS_BETTER = ("slam/rtf",)
# Wall-clock metrics depend on how many logs shared the cores and on the work done: they are compared
# only with nights that ran as many logs at once (CONCURRENCY_METRIC: 1 in-process, N for --jobs N, 0 on
# a Dask cluster) and mapped at the same rate (MAPPING_RATE_METRIC, 0.1 Hz).
WALL_CLOCK_METRICS = ("slam/rtf",)
CONCURRENCY_METRIC = "nightly/concurrent_logs"
REGRESSION_WINDOW = 5  # previous nights compared against
REGRESSION_TOLERANCE = 0.2  # flagged when 20 % worse than their median
NIGHTLY_OUTPUT_BYTES = 200_000_000  # free space asked for per log before the night starts (maps, reports)


def discover_logs(root: Path, since: dt.date | None = None) -> list[Path]:
    """ROS 2 bag directories (metadata.yaml), ROS 1 .bag and single .db3/.mcap files, recursively;
    hidden files and folders (partial writes) are skipped. `since`: modified on or after that
    day (UTC), judged by the newest file of a bag directory."""
    if not root.is_dir():
        raise InputError(root, "log folder does not exist")

    def hidden(p: Path) -> bool:
        return any(part.startswith(".") for part in p.relative_to(root).parts)

    bag_dirs = sorted({p.parent for p in root.rglob("metadata.yaml") if not hidden(p)})
    singles = sorted(p for p in root.rglob("*") if p.suffix in LOG_SUFFIXES and p.is_file() and not hidden(p)
                     and not any(d in p.parents for d in bag_dirs))
    found = bag_dirs + singles
    if since is not None:
        stamp = dt.datetime.combine(since, dt.time(), dt.UTC).timestamp()

        def mtime(p: Path) -> float:
            return max((f.stat().st_mtime for f in p.iterdir()), default=p.stat().st_mtime) if p.is_dir() \
                else p.stat().st_mtime

        found = [p for p in found if mtime(p) >= stamp]
    return sorted(found)


def hidden_logs(root: Path) -> list[str]:
    """Logs (by suffix or metadata.yaml) that discovery skipped because a part of their path
    starts with '.', relative to `root`: said, so an empty night is not a mystery."""
    if not root.is_dir():
        return []
    found = set()
    for p in root.rglob("*"):
        rel = p.relative_to(root)
        if not any(part.startswith(".") for part in rel.parts):
            continue
        if p.name == "metadata.yaml":
            found.add(str(rel.parent))
        elif p.suffix in LOG_SUFFIXES and p.is_file():
            found.add(str(rel))
    return sorted(found)


def _unique_ids(logs: list[Path], root: Path) -> dict[Path, str]:
    """Stable log ids from the path relative to LOG_DIR (nested/run.mcap -> nested_run; a slug
    plus a hash of the path for names that are not plain ASCII), so a log keeps its id across
    nights whatever else is discovered. Two plain names that read alike (a/b.mcap, a_b.mcap)
    both take the hash of their path."""
    ids = {p: stable_id(p.relative_to(root)) for p in logs}
    clashes = {i for i in ids.values() if list(ids.values()).count(i) > 1}
    return {p: f"{i}-{path_hash(p.relative_to(root))}" if i in clashes else i for p, i in ids.items()}


def _night(date: str | None) -> str:
    if date is None:
        return dt.date.today().isoformat()
    wrong = UsageError(f"--date {shorten(date)}: expected a calendar date YYYY-MM-DD")
    if not re.fullmatch(r"\d{4}-\d{2}-\d{2}", date):
        raise wrong
    try:
        return dt.date.fromisoformat(date).isoformat()  # a real calendar date: 2026-13-45 is not one
    except ValueError:
        raise wrong from None


def main(log_dir: Path, cfg: Config, *, out: Path, jobs: int, scheduler: str | None, since: str | None,
         gates: Path | None, date: str | None, pdf: bool, analysis: str = DEFAULT_ANALYSIS,
         junit: Path | None = None, force: bool = False) -> None:
    """`analysis` names the per-log function ("module:function", see log_job); tests inject fakes.
    `junit`: also write the night's gates as JUnit XML there (one test case per gate per log).
    A log already processed with this configuration (any night) is skipped unless it changed or `force`."""
    from mrnc_eval.commands.executors import make_executor

    night = _night(date)
    cfg = _with_gates(cfg, gates)
    executor = make_executor(jobs, scheduler, cfg.nightly.scheduler_timeout_s)
    concurrency = 0 if scheduler else max(1, jobs)
    since_date = _since(since)
    logs = discover_logs(log_dir, since_date)
    hidden = hidden_logs(log_dir)
    if not logs and since_date is None:  # a wrong folder, not a quiet night
        raise InputError(log_dir, "no logs found (.mcap, .db3 or .bag files, ROS 2 bag folders)" + (
            f"; {len(hidden)} hidden entr{'y' if len(hidden) == 1 else 'ies'} skipped ({', '.join(hidden[:3])}"
            f"{', ...' if len(hidden) > 3 else ''}: a name starting with '.' is a recorder's partial write; "
            "rename it to process it)" if hidden else ""))
    if hidden:
        log.warning("%s: %d hidden log(s) skipped (names starting with '.'): %s", log_dir, len(hidden),
                    ", ".join(hidden[:5]))
    check_output_root(out, need_bytes=NIGHTLY_OUTPUT_BYTES * max(1, len(logs)))
    skipped = unreadable_folders(log_dir)
    for folder in skipped:
        log.error("%s: cannot read this folder; any log in it was skipped", folder)
    with _exclusive(out / ".nightly.lock"):
        _run_night(logs, log_dir, cfg, out, night, executor, pdf, analysis, junit, force, concurrency)
    if skipped:  # reported, never silently left out of the night
        raise SomeInputsFailed(f"{len(skipped)} folder(s) of {log_dir} could not be read: "
                               + ", ".join(shorten(str(f), 120) for f in skipped[:5]))


def unreadable_folders(root: Path) -> list[str]:
    """Folders under `root` (hidden ones aside) that cannot be listed: discovery skips them
    silently (Path.rglob ignores permission errors), so the night must say so."""
    import os

    problems: list[str] = []
    for _dirpath, dirnames, _files in os.walk(root, onerror=lambda err: problems.append(str(err.filename))):
        dirnames[:] = [d for d in dirnames if not d.startswith(".")]
    return problems


@contextmanager
def _exclusive(lock_path: Path) -> Iterator[None]:
    """One nightly per report root at a time (an overlapping cron run would redo the same logs);
    the kernel drops the lock when its holder dies, even by SIGKILL."""
    import fcntl

    with open(lock_path, "a+b") as fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError as err:
            raise UsageError(f"{lock_path.parent}: another nightly job is writing this report root") from err
        try:
            yield
        finally:  # removed while still held: no lock file left behind in the report root
            lock_path.unlink(missing_ok=True)


def log_stamp(path: Path) -> str:
    """Size and modification time (ns) of a log file, or of every file of a bag directory: a log
    that is rewritten or appended to gets a new stamp (cheaper than hashing gigabytes)."""
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    return ";".join(f"{f.relative_to(path) if path.is_dir() else f.name}:{f.stat().st_size}:{f.stat().st_mtime_ns}"
                    for f in files)


def plan_night(logs: dict[str, str], cfg_hash: str, last: dict[str, LastRun], night: str, night_dir: Path,
               force: bool) -> dict[str, str]:
    """log_id -> "new" | "unchanged" | "re-run". `logs`: log_id -> stamp. Unchanged: its last run
    succeeded with this configuration on this very log (and, on this night, its folder is there)."""
    plan = {}
    for log_id, stamp in logs.items():
        prev = last.get(log_id)
        same = (prev is not None and prev.status == "ok" and prev.config_hash == cfg_hash and prev.log_stamp == stamp
                and (prev.night != night or (night_dir / "logs" / log_id).is_dir()))
        plan[log_id] = "new" if prev is None else "unchanged" if same and not force else "re-run"
    return plan


def _run_night(logs: list[Path], log_dir: Path, cfg: Config, out: Path, night: str, executor: Executor, pdf: bool,
               analysis: str, junit: Path | None = None,
               force: bool = False, concurrency: int = 1) -> None:
    night_dir = out / night
    history = History(out / "history.sqlite")
    ids = _unique_ids(logs, log_dir)
    stamps = {p: log_stamp(p) for p in logs}
    plan = plan_night({ids[p]: stamps[p] for p in logs}, config_hash(cfg), history.last_runs(), night, night_dir,
                      force)
    config_yaml = dump_config(cfg)
    todo = [LogJob(log_path=str(p), log_id=ids[p], config_yaml=config_yaml, out_dir=str(night_dir / "logs" / ids[p]),
                   pdf=pdf, analysis=analysis) for p in logs
            if plan[ids[p]] != "unchanged"]
    log.info("night %s: %d logs, %d to process", night, len(logs), len(todo))
    by_path = {str(p): stamps[p] for p in logs}
    night_existed = night_dir.exists()
    try:
        with progress_bar(len(todo)) as bar:
            task = bar.add_task(f"night {night}", total=len(todo)) if bar else None
            for summary in executor.run(todo):
                _record(history, night, summary, by_path.get(summary.log_path, ""), concurrency)
                if bar and task is not None:
                    bar.update(task, advance=1, description=f"night {night}: {summary.log_id} {summary.status}")
    except BaseException:  # Ctrl-C (errors.Interrupted), a crash: leave no half-written night folder
        _close_interrupted_night(history, night, night_dir, night_existed)
        raise
    rows = _write_index(history, night, night_dir)
    link_latest(night_dir)
    regressions = _write_trends(history, out)
    if junit is not None:
        from mrnc_eval.commands.junit import night_suites
        from mrnc_eval.reports.junit import write_junit

        # a recurring job: each night replaces the XML it wrote the night before (only that, outputs.py)
        write_junit(junit, night_suites(rows, night_dir, cfg.gates, (cfg.slam.method,)), f"mrnc-eval nightly {night}",
                    force=True)
    failed = [r for r in rows if r.status != "ok"]
    gate_fail = [r for r in rows if r.gates_failed]
    counts = {kind: sum(v == kind for v in plan.values()) for kind in ("new", "unchanged", "re-run")}
    sys.stdout.write(f"night {night}: {counts['new']} new, {counts['unchanged']} unchanged, {counts['re-run']} re-run"
                     f" (--force re-runs all); {len(rows)} logs, {len(failed)} failed, {len(gate_fail)} with failed"
                     " gates, "
                     f"{len(regressions)} trend regressions -> {night_dir / 'index.html'}\n")
    if failed:
        raise SomeInputsFailed("; ".join(f"{r.log_id}: {r.error}" for r in failed))
    if gate_fail:
        raise GateFailed("gates failed: " + "; ".join(f"{r.log_id}: {', '.join(r.gates_failed)}"
                                                      for r in gate_fail))


def _close_interrupted_night(history: History, night: str, night_dir: Path, night_existed: bool) -> None:
    """A night stopped part-way: a night folder this run created with no finished log in it is
    removed; otherwise its index is written over what finished (the next run resumes the rest).
    Per-log folders are only moved into place when complete, so none is half-written."""
    import shutil

    try:
        if not night_existed and not history.runs(night):
            shutil.rmtree(night_dir, ignore_errors=True)
        elif night_dir.is_dir():
            _write_index(history, night, night_dir)
    except Exception as err:  # noqa: BLE001 - already stopping: say it, keep the original exception
        log.error("%s: could not close the interrupted night: %s", night_dir, err)


def _with_gates(cfg: Config, gates: Path | None) -> Config:
    if gates is None:
        return cfg
    try:
        data = load_yaml_file(gates, "gates") or {}
        if not isinstance(data, dict):
            raise ConfigError("expected a mapping of gate names to limits")
        return build(Config, {**as_dict(cfg), "gates": {**as_dict(cfg.gates), **data}})
    except (OSError, yaml.YAMLError, ConfigError, TypeError) as err:
        raise ConfigError(f"{gates}: invalid gates file: {err}") from err


def _since(since: str | None) -> dt.date | None:
    try:
        return dt.date.fromisoformat(since) if since else None
    except ValueError as err:
        raise UsageError(f"--since {since!r}: expected YYYY-MM-DD") from err


def _record(history: History, night: str, s: LogSummary, stamp: str, concurrency: int = 1) -> None:
    """One (night, log) row set, written in one transaction once the log is complete."""
    metrics = (*s.metrics, ("gates_failed", float(len(s.gates_failed)), ""),
               *((f"gate_failed/{label}", 1.0, "") for label in s.gates_failed),
               (CONCURRENCY_METRIC, float(concurrency), ""))
    history.record(LogRecord(night=night, log_id=s.log_id, run_id=s.run_id, log_path=s.log_path,
                             tool_version=s.tool_version, config_hash=s.config_hash, status=s.status, error=s.error,
                             finished_utc=dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"), metrics=metrics,
                             log_stamp=stamp))


INDEX_COLUMNS = (  # (label, metric, format): the worst value over the log's groups
    ("APE RMSE (m)", "slam/ape/ape_rmse_m", "{:.4f}"),
    ("RTF", "slam/rtf", "{:.2f}"),
    ("mapping rate (Hz)", "slam/mapping_rate_hz", "{:.1f}"),  # the work the RTF was measured at
    ("funnel violations", "funnel_violations", "{:.0f}"),
    ("saturation ratio", "saturation_ratio", "{:.3f}"),
    ("safety stops", "safety_stops", "{:.0f}"),
    ("cross-track RMS (m)", "cross_track_rms_m", "{:.3f}"),
)


def _write_index(history: History, night: str, night_dir: Path) -> list[IndexRow]:
    from mrnc_eval.reports.night import render_index

    values: dict[str, dict[str, float]] = {}
    for _, log_id, metric, value in history.metric_series(night):
        values.setdefault(log_id, {})[metric] = value
    rows = []
    for log_id, status, error, log_path in history.runs(night):
        mine = values.get(log_id, {})
        cells = []
        for _label, key, fmt in INDEX_COLUMNS:
            hits = [v for m, v in mine.items() if m == key or ("/" not in key and m.endswith("/" + key))]
            cells.append(fmt.format(max(hits)) if hits else "\u2013")
        here = night_dir / "logs" / log_id
        rows.append(IndexRow(
            log_id=log_id, log_path=log_path, status=status, error=error, cells=tuple(cells),
            report=f"logs/{log_id}/report.html" if (here / "report.html").exists() else "",
            pdf=f"logs/{log_id}/report.pdf" if (here / "report.pdf").exists() else "",
            gates_failed=tuple(sorted(m.split("/", 1)[1] for m in mine if m.startswith("gate_failed/")))))
    html = render_index(night, rows, [c[0] for c in INDEX_COLUMNS])
    atomic_write_text(night_dir / "index.html", html)
    return rows


def _comparable(per_log: dict[str, dict[str, float]],
                work: dict[tuple[str, str], tuple[float, float]]) -> dict[str, dict[str, float]]:
    """Per log, only the nights that ran under the same work as its latest night: as many logs at
    once and the same mapping rate (a wall-clock metric of a --jobs 2 night, or of a night that mapped
    every sweep, is not a regression against a --jobs 1 night at LIO-SAM's rate)."""
    out = {}
    for log_id, by_night in per_log.items():
        latest = work.get((max(by_night), log_id))
        out[log_id] = {n: v for n, v in by_night.items() if work.get((n, log_id)) == latest}
    return out


def _write_trends(history: History, out: Path) -> list[Regression]:
    from mrnc_eval.reports.night import render_trends

    data: dict[str, dict[str, dict[str, float]]] = {}
    concurrency: dict[tuple[str, str], float] = {}  # (night, log) -> logs that ran at once
    for night, log_id, metric, value in history.metric_series():
        if metric in TREND_METRICS:
            data.setdefault(metric, {}).setdefault(log_id, {})[night] = value
        elif metric == CONCURRENCY_METRIC:
            concurrency[(night, log_id)] = value
    rate = data.get(MAPPING_RATE_METRIC, {})
    work = {key: (logs, round(rate.get(key[1], {}).get(key[0], 0.0), 1)) for key, logs in concurrency.items()}
    data = {m: data[m] for m in TREND_METRICS if m in data}  # SLAM first, then control
    flagged = {metric: find_regressions(metric, _comparable(per_log, work) if metric in WALL_CLOCK_METRICS
                                        else per_log, REGRESSION_WINDOW, REGRESSION_TOLERANCE,
                                        higher_is_better=metric in HIGHER_IS_BETTER)
               for metric, per_log in data.items()}
    regressions = [r for found in flagged.values() for r in found]
    html = render_trends(history.nights(), data, flagged, REGRESSION_WINDOW, REGRESSION_TOLERANCE)
    atomic_write_text(out / "trends.html", html)
    return regressions
