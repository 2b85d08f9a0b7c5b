"""`mrnc-eval compare RUN_A RUN_B` (result directories or evo result zips) and
`compare --history ROOT --nights D1 D2`: the same metrics side by side with their difference and
the configuration keys that differ, as a table for the terminal, Markdown or HTML. Reads result
directories or the nightly history; never recomputes."""

from __future__ import annotations

import html
import logging
import sys
from pathlib import Path
from typing import Any

import yaml

from mrnc_eval.config import CONFIG_FILE_NAME
from mrnc_eval.errors import InputError, UsageError
from mrnc_eval.outputs import claim_output, write_output
from mrnc_eval.reports.compare import RunMetrics, config_table, flatten, metrics_table, mismatch_warnings
from mrnc_eval.results import metric_direction, read_result
from mrnc_eval.tables import Table

FORMATS = ("terminal", "markdown", "html")
log = logging.getLogger(__name__)


def _config_of(path: Path) -> dict[str, Any] | None:
    if not path.is_file():
        return None
    try:
        return flatten(yaml.safe_load(path.read_text(encoding="utf-8")) or {})
    except (OSError, yaml.YAMLError) as err:
        raise InputError(path, f"unreadable configuration: {err}") from err


def evo_metrics(path: Path, label: str) -> RunMetrics:
    """The statistics of an evo result zip (evo_ape/evo_rpe/mrnc-eval --save_results), keyed by
    its label and title's first line ("APE (m)/rmse"), so two evo zips line up; read without pickle."""
    from mrnc_eval.io.evo_results import read_evo_zip

    res = read_evo_zip(path)
    kind = res.info.get("label", "result")
    unit = kind[kind.find("(") + 1:kind.rfind(")")] if "(" in kind else ""
    unit = "" if unit == "unit-less" else unit
    metrics: dict[str, tuple[float | None, str]] = {f"{kind}/{k}": (v, unit) for k, v in res.stats.items()}
    config = {"evo.title": res.title.replace("\n", " "), "evo.ref_name": res.info.get("ref_name", ""),
              "evo.est_name": res.est_name}
    return RunMetrics(label, metrics, config, {k: True for k in metrics})


def run_metrics(run: Path, label: str) -> RunMetrics:
    """The metrics of a result directory, of the result directories in a folder (one log's), or
    of an evo result zip."""
    from mrnc_eval.commands.report import result_dirs_of

    if Path(run).suffix.lower() == ".zip":  # read_evo_zip says what is wrong with a zip that is not evo's
        return evo_metrics(run, label)

    dirs = result_dirs_of([run])
    results = [read_result(d) for d in dirs]
    metrics = {f"{m.group}/{m.name}": (m.value, m.unit) for r in results for m in r.metrics}
    lower = {f"{m.group}/{m.name}": metric_direction(m.name, m.lower_is_better) for r in results for m in r.metrics}
    config = next((c for d in dirs if (c := _config_of(d / CONFIG_FILE_NAME)) is not None), None)
    return RunMetrics(label, metrics, config, lower, logs=frozenset(r.log_path for r in results if r.kind != "info"),
                      kinds=frozenset(r.kind for r in results if r.kind != "info"))


def night_metrics(root: Path, night: str, log_id: str | None) -> RunMetrics:
    """A night's metrics from the history (per log, or of one log); its configuration from the
    night's per-log folders (the nightly runs every log of a night with one configuration)."""
    from mrnc_eval.history import open_history

    history = open_history(root)
    path, nights = history.path, history.nights()
    if night not in nights:
        raise InputError(path, f"night {night} is not in the history (nights: {', '.join(nights)})")
    rows = [r for r in history.metric_rows(night) if r.status == "ok" and (log_id is None or r.log_id == log_id)]
    if not rows:
        raise InputError(path, f"night {night} has no metrics" + (f" for log {log_id}" if log_id else ""))
    metrics = {(r.metric if log_id else f"{r.log_id}: {r.metric}"): (r.value, r.unit) for r in rows
               if not r.metric.startswith("gate_failed/")}
    lower = {key: metric_direction(key.rsplit("/", 1)[-1]) for key in metrics}
    logs_dir = root / night / "logs"
    configs = sorted(logs_dir.glob(f"{log_id or '*'}/*/{CONFIG_FILE_NAME}")) if logs_dir.is_dir() else []
    return RunMetrics(f"night {night}" + (f", {log_id}" if log_id else ""), metrics,
                      _config_of(configs[0]) if configs else None, lower)


def render(tables: list[Table], fmt: str) -> str:
    from mrnc_eval.reports.render import css
    from mrnc_eval.reports.tables import render_table

    if fmt == "markdown":
        return "\n".join(render_table(t, "markdown") for t in tables)
    body = "".join(render_table(t, "html") for t in tables)
    return (f"<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>{html.escape(tables[0].title)}</title>"
            f"<style>{css()}</style></head><body><h1>mrnc-eval compare</h1>{body}</body></html>\n")


def print_rich(tables: list[Table]) -> None:
    from rich.markup import escape
    from rich.table import Table as RichTable

    from mrnc_eval.reports.tables import fmt_cell
    from mrnc_eval.text import console as terminal_console

    console = terminal_console(highlight=False)  # full width off a terminal
    for table in tables:
        rt = RichTable(title=escape(table.title), title_justify="left")
        rt.add_column("", no_wrap=True)  # metric keys stay whole; the numbers' columns give way
        for c in table.column_labels:
            rt.add_column(escape(c), justify="right")
        for label, row in zip(table.row_labels, table.cells, strict=True):
            rt.add_row(escape(label), *[escape(fmt_cell(c, table.precision)) for c in row])
        console.print(rt)
        for note in table.notes:
            console.print(escape(note), style="dim")


def compare_tables(runs: list[Path], *, history: Path | None = None, nights: tuple[str, str] | None = None,
                   log_id: str | None = None, only_changed: bool = False) -> list[Table]:
    """[metrics table, configuration table] of two runs or of two nights of a history."""
    if history is not None:
        if nights is None or runs:
            raise UsageError("--history needs --nights D1 D2 and no RUN arguments")
        a, b = (night_metrics(history, n, log_id) for n in nights)
    else:
        if len(runs) != 2:
            raise UsageError(f"compare needs two runs (RUN_A RUN_B), got {len(runs)}")
        a, b = run_metrics(runs[0], str(runs[0])), run_metrics(runs[1], str(runs[1]))
    for warning in mismatch_warnings(a, b):
        log.warning("%s", warning.removeprefix("WARNING: "))
    return [metrics_table(a, b, only_changed=only_changed), config_table(a, b)]


def main(runs: list[Path], *, history: Path | None, nights: tuple[str, str] | None, log_id: str | None,
         fmt: str, out: Path | None, only_changed: bool, force: bool = False) -> None:
    if fmt not in FORMATS:
        raise UsageError(f"--format {fmt!r}: choose one of {', '.join(FORMATS)}")
    if out is not None:
        fmt = {".md": "markdown", ".html": "html", ".htm": "html"}.get(out.suffix.lower(), "")
        if not fmt:
            raise UsageError(f"--out {out}: use a .md or .html file")
        claim_output(out, force=force, inputs=runs)
    tables = compare_tables(runs, history=history, nights=nights, log_id=log_id, only_changed=only_changed)
    if out is not None:
        write_output(out, render(tables, fmt), force=force, inputs=runs)
        sys.stdout.write(f"{out}\n")
    elif fmt == "terminal":
        print_rich(tables)
    else:
        sys.stdout.write(render(tables, fmt))
