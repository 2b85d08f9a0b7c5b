"""`--junit OUT.xml` of `nightly` and `report`: the gate results of logs as JUnit XML.

Gates are read from what the night wrote (each log's result directories, judged by the same
evaluate_gates as its report); a log whose analysis failed becomes errors, never passes."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from mrnc_eval.evaluation.config import GatesConfig
from mrnc_eval.reports.junit import LogSuite, error_suite, suite_of_results
from mrnc_eval.reports.night import IndexRow
from mrnc_eval.results import RunResult, read_result


def results_in(log_dir: Path) -> list[RunResult]:
    """The result directories one level below a nightly per-log folder."""
    from mrnc_eval.commands.report import result_dirs_of

    return [read_result(d) for d in result_dirs_of([log_dir])]


def night_suites(rows: Sequence[IndexRow], night_dir: Path, gates: GatesConfig,
                 methods: Sequence[str] = ("lio",)) -> list[LogSuite]:
    """One suite per row of the night index; `methods`: the SLAM methods the night runs (they name
    the APE gate of every log, also of one that failed)."""
    from mrnc_eval.errors import InputError

    suites = []
    for row in rows:
        if row.status != "ok":
            suites.append(error_suite(row.log_id, row.log_path, row.error, gates, methods))
            continue
        try:
            results = results_in(night_dir / "logs" / row.log_id)
        except InputError as err:
            suites.append(error_suite(row.log_id, row.log_path, f"results unreadable: {err}", gates, methods))
            continue
        suites.append(suite_of_results(row.log_id, row.log_path, results, gates, methods))
    return suites
