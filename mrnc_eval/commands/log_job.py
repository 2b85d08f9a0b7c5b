"""One log of the nightly job. Runs in a worker (this process, a spawned pool process or a Dask
worker) and returns a picklable `LogSummary`; never raises.

The analysis itself is injectable as a "module:function" name (resolved inside the worker, so
it travels to spawned processes and Dask workers by name): the default runs the real
pipelines (info, SLAM, control replay, report); tests pass small fakes. Whatever the analysis,
its outputs are written under a partial directory and moved into place only when complete."""

from __future__ import annotations

import datetime as dt
import importlib
import math
import numbers
import shutil
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

from mrnc_eval import __version__
from mrnc_eval.config import Config
from mrnc_eval.history import RunStatus

DEFAULT_ANALYSIS = "mrnc_eval.commands.log_job:analyse_log"
MetricRow = tuple[str, float | None, str]  # (metric, value, unit)


@dataclass(frozen=True, kw_only=True)
class LogJob:
    log_path: str
    log_id: str  # safe, unique within the night
    config_yaml: str
    out_dir: str  # the log's final report directory
    pdf: bool = True
    analysis: str = DEFAULT_ANALYSIS


@dataclass(kw_only=True)
class Analysis:
    metrics: list[MetricRow] = field(default_factory=list)
    gates_failed: list[str] = field(default_factory=list)  # labels of the gate cards that failed


@dataclass(frozen=True, kw_only=True)
class LogSummary:
    """What a worker reports for one log of the night (picklable: plain fields only)."""

    log_id: str
    log_path: str
    status: RunStatus
    error: str = ""
    metrics: tuple[MetricRow, ...] = ()
    gates_failed: tuple[str, ...] = ()  # labels of the gate cards that failed
    report: str = ""  # the HTML report's path, "" when none was written
    config_hash: str = ""
    tool_version: str = __version__
    run_id: str = ""
    traceback: str = ""  # for bugs (not MrncError), to find them in the logs

    @property
    def ok(self) -> bool:
        return self.status == "ok"


AnalyseFn = Callable[[Path, Config, Path, str, bool], Analysis]  # (log, cfg, work dir, log id, pdf)


def resolve(name: str) -> AnalyseFn:
    module, _, attr = name.partition(":")
    return getattr(importlib.import_module(module), attr)


def analyse_log(log_path: Path, cfg: Config, work_dir: Path, log_id: str, pdf: bool) -> Analysis:
    """The real per-log analysis: info, SLAM, control replay when the log has a path and wheel
    speeds, the HTML/PDF report; each as a result directory under work_dir."""
    from mrnc_eval.commands import control, info, slam
    from mrnc_eval.config import config_hash, dump_config
    from mrnc_eval.reports.gates import evaluate_gates
    from mrnc_eval.reports.render import write_report
    from mrnc_eval.results import RunResult, absolute_log_path, write_result
    from mrnc_eval.schema.info import INFO

    config_yaml = dump_config(cfg)
    summary = info.run(log_path, cfg).to_json()
    info_result = RunResult(kind="info", log_path=absolute_log_path(log_path), log_id=log_id, extra={INFO: summary},
                            config_hash=config_hash(cfg))
    write_result(info_result, work_dir / "info", config_yaml)
    results = [info_result, slam.run_log(log_path, cfg, work_dir / "slam", log_id=log_id)]
    missing = [r for r in ("path", "wheel_speeds") if r not in summary["roles"]]
    if missing:
        info_result.warnings.append(f"control replay skipped: the log has no {' and no '.join(missing)} topic")
    else:
        results.append(control.run_log(log_path, cfg, work_dir / "control", mode="replay", log_id=log_id))
    write_report(results, work_dir, gates=cfg.gates, config_text=config_yaml, pdf=pdf, force=True)  # its own folder
    metrics = [(f"{m.group}/{m.name}", _finite(m.value), m.unit) for r in results for m in r.metrics]
    failed = [g.label for g in evaluate_gates(results, cfg.gates) if g.status == "fail"]
    return Analysis(metrics=metrics, gates_failed=failed)


def process_log(job: LogJob) -> LogSummary:
    """Run job.analysis into a partial directory, move it into place, summarise. A failure
    becomes a summary with status "failed" and the error (and traceback for bugs)."""
    import yaml

    from mrnc_eval.config import build, config_hash
    from mrnc_eval.errors import MrncError, raise_if_interrupted

    target = Path(job.out_dir)
    partial = target.with_name(f".{target.name}.partial")
    run_id = f"{job.log_id}-{dt.datetime.now(dt.UTC).strftime('%Y%m%dT%H%M%S.%fZ')}"
    partial_summary = LogSummary(log_id=job.log_id, log_path=job.log_path, status="failed", run_id=run_id)
    try:
        cfg = build(Config, yaml.safe_load(job.config_yaml) or {})
        partial_summary = replace(partial_summary, config_hash=config_hash(cfg))
        shutil.rmtree(partial, ignore_errors=True)
        partial.mkdir(parents=True)
        outcome = resolve(job.analysis)(Path(job.log_path), cfg, partial, job.log_id, job.pdf)
        _move_into_place(partial, target)
        report = target / "report.html"
        return replace(partial_summary, status="ok",
                       metrics=tuple((str(n), _finite(v), str(u)) for n, v, u in outcome.metrics),
                       gates_failed=tuple(outcome.gates_failed), report=str(report) if report.exists() else "")
    except MrncError as err:
        raise_if_interrupted()  # a stage cut short by a swallowed Ctrl-C is the interrupt, not this log's failure
        return replace(partial_summary, error=str(err))
    except Exception as err:  # noqa: BLE001 - a bug on one log fails that log (traceback kept), not the night
        raise_if_interrupted()
        return replace(partial_summary, error=f"{type(err).__name__}: {err}", traceback=traceback.format_exc())
    finally:
        shutil.rmtree(partial, ignore_errors=True)


def _move_into_place(partial: Path, target: Path) -> None:
    """A re-run of the night replaces this log's previous outputs whole."""
    if not target.exists():
        partial.replace(target)
        return
    old = target.with_name(f".{target.name}.old")
    shutil.rmtree(old, ignore_errors=True)
    target.replace(old)
    partial.replace(target)
    shutil.rmtree(old, ignore_errors=True)


def failed_summary(job: LogJob, error: str) -> LogSummary:
    """Summary of a job whose worker died before it could answer (native crash, killed, lost)."""
    return LogSummary(log_id=job.log_id, log_path=job.log_path, status="failed", error=error)


def _finite(v: object) -> float | None:
    if v is None or isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v):
        return None
    return float(v)
