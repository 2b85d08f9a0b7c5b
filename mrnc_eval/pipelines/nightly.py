"""`mrnc-eval nightly`: every new log of a folder -> SLAM + control + report, a night index,
trends across nights, and a metrics history. Safe to run unattended: per-log outputs are
moved into place when complete, history is written per log in one transaction, a killed night
resumes where it stopped, earlier nights are never modified."""

from __future__ import annotations

import datetime as dt
import logging
import re
import sys
from pathlib import Path

import numpy as np
import yaml

from mrnc_eval import __version__
from mrnc_eval.config import Config, build, dump_config
from mrnc_eval.errors import ConfigError, GateFailed, InputError, SomeInputsFailed, UsageError
from mrnc_eval.evaluation.config import GatesConfig
from mrnc_eval.pipelines.history import History, LogRecord
from mrnc_eval.pipelines.progress import progress_bar
from mrnc_eval.results import atomic_write_text, log_id_for

log = logging.getLogger(__name__)
LOG_SUFFIXES = (".mcap", ".db3", ".bag")
TREND_METRICS = ("slam/ape/ape_rmse_m", "slam/rtf", "control/recorded/left/rms_error_mps",
                 "control/recorded/right/rms_error_mps", "control/recorded/path/cross_track_rms_m")
REGRESSION_WINDOW = 5
REGRESSION_TOLERANCE = 0.2  # 20 % worse than the median of the previous nights


def discover_logs(root: Path, since: dt.date | None = None) -> list[Path]:
    """ROS 1 bags, ROS 2 bag directories (metadata.yaml) and single .db3/.mcap files, recursively."""
    if not root.is_dir():
        raise InputError(root, "log folder does not exist")
    found: list[Path] = []
    bag_dirs = {p.parent for p in root.rglob("metadata.yaml")}
    found += sorted(bag_dirs)
    for p in sorted(root.rglob("*")):
        if p.is_file() and p.suffix in LOG_SUFFIXES and not any(d in p.parents for d in bag_dirs):
            found.append(p)
    if since is not None:
        stamp = dt.datetime.combine(since, dt.time(), dt.UTC).timestamp()
        found = [p for p in found if p.stat().st_mtime >= stamp]
    return found


def _unique_ids(logs: list[Path], root: Path) -> dict[Path, str]:
    """Log ids unique within the night (same file name in two folders gets its folder prefixed)."""
    ids: dict[Path, str] = {}
    seen: dict[str, int] = {}
    for p in logs:
        base = log_id_for(p)
        if base in seen:
            base = log_id_for("_".join(p.relative_to(root).parts))
        seen[base] = seen.get(base, 0) + 1
        ids[p] = base
    return ids


def _night(date: str | None) -> str:
    if date is None:
        return dt.date.today().isoformat()
    if not re.fullmatch(r"\d{4}-\d{2}-\d{2}", date):
        raise UsageError(f"--date {date!r}: expected YYYY-MM-DD")
    return date


def main(log_dir: Path, cfg: Config, *, out: Path, jobs: int, scheduler: str | None, since: str | None,
         gates: Path | None, date: str | None, pdf: bool) -> None:
    from mrnc_eval.pipelines import executors

    night = _night(date)
    if gates is not None:
        try:
            data = yaml.safe_load(gates.read_text(encoding="utf-8")) or {}
            cfg = build(Config, {**_plain(cfg), "gates": {**_plain(cfg.gates), **data}})
        except (OSError, yaml.YAMLError, ConfigError, TypeError) as err:
            raise ConfigError(f"{gates}: invalid gates file: {err}") from err
    since_date = dt.date.fromisoformat(since) if since else None
    logs = discover_logs(log_dir, since_date)
    night_dir = out / night
    history = History(out / "history.sqlite")
    done = history.finished(night)
    ids = _unique_ids(logs, log_dir)
    config_yaml = dump_config(cfg)
    todo = [(str(p), config_yaml, str(night_dir / "logs" / ids[p]), pdf) for p in logs
            if not (ids[p] in done and (night_dir / "logs" / ids[p] / "report.html").exists())]
    log.info("night %s: %d logs, %d to process", night, len(logs), len(todo))
    if jobs < 1:
        raise UsageError("--jobs must be >= 1")
    if scheduler:
        stream = executors.run_dask(todo, scheduler)
    elif jobs == 1:
        stream = executors.run_in_process(todo)
    else:
        stream = executors.run_local_pool(todo, jobs)
    with progress_bar(len(todo)) as b:
        task = b.add_task("logs", total=len(todo)) if b else None
        for summary in stream:
            _record(history, night, summary, ids)
            if b:
                b.advance(task)
    rows = _write_index(history, night, night_dir, cfg.gates)
    _write_trends(history, out)
    failed = [r for r in rows if r["status"] != "ok"]
    gate_fail = [r for r in rows if r["gates_failed"]]
    sys.stdout.write(f"night {night}: {len(rows)} logs, {len(failed)} failed, {len(gate_fail)} with failed gates -> "
                     f"{night_dir / 'index.html'}\n")
    if failed:
        raise SomeInputsFailed("; ".join(f"{r['log_id']}: {r['error']}" for r in failed))
    if gate_fail:
        raise GateFailed("gates failed: " + "; ".join(f"{r['log_id']}: {', '.join(r['gates_failed'])}" for r in gate_fail))


def _plain(obj) -> dict:
    from mrnc_eval.config import as_dict

    return as_dict(obj)


def _record(history: History, night: str, s: dict, ids: dict[Path, str]) -> None:
    log_id = ids.get(Path(s["log_path"]), s["log_id"])
    metrics = tuple((n, v, u) for n, v, u in s["metrics"]) + (("gates_failed", float(len(s["gates_failed"])), ""),)
    history.record(LogRecord(night, log_id, s.get("run_id", ""), s["log_path"], s.get("tool_version", __version__),
                             s.get("config_hash", ""), s["status"], s.get("error", ""),
                             dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"), metrics))


def _write_index(history: History, night: str, night_dir: Path, gates: GatesConfig) -> list[dict]:
    from mrnc_eval.reports.render import _env, css

    series = {}
    for n, log_id, metric, value in history.metric_series():
        if n == night:
            series[(log_id, metric)] = value
    rows = []
    for log_id, status, error, _path in history.runs(night):
        fmt = lambda key, f="{:.3f}": f.format(series[(log_id, key)]) if (log_id, key) in series else "–"  # noqa: E731
        report = night_dir / "logs" / log_id / "report.html"
        gates_failed = [] if series.get((log_id, "gates_failed"), 0) == 0 else _gate_names(night_dir / "logs" / log_id)
        rows.append({"log_id": log_id, "status": status, "error": error,
                     "report": f"logs/{log_id}/report.html" if report.exists() else "",
                     "ape": fmt("slam/ape/ape_rmse_m", "{:.4f}"),
                     "funnel": fmt("control/recorded/left/funnel_violations", "{:.0f}"),
                     "stops": fmt("control/recorded/left/safety_stops", "{:.0f}"), "gates_failed": gates_failed})
    html = _env().get_template("index.html.j2").render(
        css=css(), night=night, tool_version=__version__, rows=rows, failed=sum(r["status"] != "ok" for r in rows),
        gate_failures=sum(bool(r["gates_failed"]) for r in rows))
    atomic_write_text(night_dir / "index.html", html)
    return rows


def _gate_names(log_dir: Path) -> list[str]:
    text = (log_dir / "report.html").read_text(encoding="utf-8") if (log_dir / "report.html").exists() else ""
    names = re.findall(r'<div class="card fail"><div class="l">([^<]+)</div>', text)
    return names or ["gate"]


def _write_trends(history: History, out: Path) -> None:
    from markupsafe import Markup
    from matplotlib.figure import Figure

    from mrnc_eval.reports.figures import _svg
    from mrnc_eval.reports.render import _env, css

    nights = history.nights()
    data: dict[str, dict[str, dict[str, float]]] = {}
    for night, log_id, metric, value in history.metric_series():
        if metric in TREND_METRICS:
            data.setdefault(metric, {}).setdefault(log_id, {})[night] = value
    figures, regressions = [], []
    for metric, per_log in data.items():
        fig = Figure(figsize=(7, 2.8), layout="constrained")
        ax = fig.add_subplot()
        for log_id, by_night in sorted(per_log.items()):
            xs = [n for n in nights if n in by_night]
            ax.plot(xs, [by_night[n] for n in xs], marker="o", lw=1, label=log_id)
            if len(xs) > 1:
                prev = [by_night[n] for n in xs[:-1]][-REGRESSION_WINDOW:]
                last, ref = by_night[xs[-1]], float(np.median(prev))
                higher_is_better = metric.endswith("rtf")
                worse = last < ref * (1 - REGRESSION_TOLERANCE) if higher_is_better else last > ref * (1 + REGRESSION_TOLERANCE) + 1e-12
                if worse:
                    regressions.append(f"{log_id}: {metric} {last:.4g} on {xs[-1]} vs median {ref:.4g} "
                                       f"of the previous {len(prev)} nights")
        ax.set_title(metric)
        ax.tick_params(axis="x", labelrotation=30, labelsize="small")
        if len(per_log) <= 8:
            ax.legend(fontsize="x-small")
        figures.append((metric, Markup(_svg(fig))))
    html = _env().get_template("trends.html.j2").render(css=css(), nights=nights, figures=figures,
                                                        regressions=regressions, window=REGRESSION_WINDOW,
                                                        tolerance_pct=int(REGRESSION_TOLERANCE * 100))
    atomic_write_text(out / "trends.html", html)
