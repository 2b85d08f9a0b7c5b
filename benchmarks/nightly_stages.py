"""Where a nightly log's time goes: the stages of the nightly's per-log analysis
(`commands/log_job.analyse_log`: info, SLAM, control replay, report HTML, report PDF), each timed in
wall and CPU seconds (CPU: all threads of this process), in one fresh process per log, in the order
the nightly runs them. The first log pays the imports; they are timed as their own rows.

    PYTHONPATH=. python benchmarks/nightly_stages.py sample_logs/circle_soft_ground.mcap [--no-pdf]

Prints a Markdown table (docs/performance.md) and the process's peak resident memory.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

T = TypeVar("T")
ROWS: list[tuple[str, float, float]] = []  # (stage, wall s, CPU s)


def timed(stage: str, work: Callable[[], T]) -> T:
    wall0, cpu0 = time.perf_counter(), time.process_time()
    out = work()
    ROWS.append((stage, time.perf_counter() - wall0, time.process_time() - cpu0))
    return out


def _imports() -> None:
    from mrnc_eval.commands import control, info, slam  # noqa: F401
    from mrnc_eval.reports import render  # noqa: F401


def analyse(log: Path, work: Path, pdf: bool) -> None:
    """The steps of analyse_log, one row each (same calls, same order)."""
    from mrnc_eval.commands import control, info, slam
    from mrnc_eval.config import Config, config_hash, dump_config
    from mrnc_eval.reports.render import write_report
    from mrnc_eval.results import RunResult, absolute_log_path, write_result
    from mrnc_eval.schema.info import INFO

    cfg = Config()
    config_yaml = dump_config(cfg)
    summary = timed("info (read, validate, roles, health)", lambda: info.run(log, cfg).to_json())
    info_result = RunResult(kind="info", log_path=absolute_log_path(log), log_id=log.stem, extra={INFO: summary},
                            config_hash=config_hash(cfg))
    write_result(info_result, work / "info", config_yaml)
    results = [info_result, timed("slam (lio, replay + outputs)",
                                  lambda: slam.run_log(log, cfg, work / "slam", log_id=log.stem))]
    if all(r in summary["roles"] for r in ("path", "wheel_speeds")):
        results.append(timed("control (replay of the chain + outputs)",
                             lambda: control.run_log(log, cfg, work / "control", mode="replay", log_id=log.stem)))
    timed("report HTML (figures, tables)",
          lambda: write_report(results, work / "html", gates=cfg.gates, config_text=config_yaml, force=True))
    if pdf:
        timed("report HTML + PDF (WeasyPrint)",
              lambda: write_report(results, work / "pdf", gates=cfg.gates, config_text=config_yaml, pdf=True,
                                   force=True))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("log", type=Path)
    parser.add_argument("--no-pdf", action="store_true")
    args = parser.parse_args()
    timed("imports (info, slam, control, report modules)", _imports)
    work = Path(tempfile.mkdtemp(prefix="nightly-stages-"))
    try:
        analyse(args.log, work, pdf=not args.no_pdf)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f"{args.log.name}, load average {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print("| stage | wall s | CPU s |\n|---|---|---|")
    for stage, wall, cpu in ROWS:
        print(f"| {stage} | {wall:.2f} | {cpu:.2f} |")
    print(f"| **total** | {sum(r[1] for r in ROWS):.2f} | {sum(r[2] for r in ROWS):.2f} |")
    with open("/proc/self/status") as status:
        print(next((line.strip() for line in status if line.startswith("VmHWM")), "VmHWM: n/a"))


if __name__ == "__main__":
    main()
