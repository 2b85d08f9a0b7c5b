"""Small per-log analyses injected into the nightly job (`analysis="module:function"`), so the
executors, history and resume logic are tested in seconds. They read the log for real (info)
and render a real report; only SLAM and control are left out."""

from __future__ import annotations

import os
import time
from pathlib import Path

from mrnc_eval.commands.log_job import Analysis
from mrnc_eval.config import Config, config_hash, dump_config
from mrnc_eval.results import Metric, RunResult, write_result

CALLS_ENV = "MRNC_TEST_CALLS_DIR"  # one file per call, to count how often each log was analysed
SLEEP_ENV = "MRNC_TEST_SLEEP_S"


def info_analysis(log_path: Path, cfg: Config, work_dir: Path, log_id: str, pdf: bool) -> Analysis:
    from mrnc_eval.commands import info
    from mrnc_eval.reports.render import write_report

    calls = os.environ.get(CALLS_ENV)
    if calls:
        Path(calls, f"{log_id}.{os.getpid()}.{time.monotonic_ns()}").touch()
    summary = info.run(log_path, cfg).to_json()
    time.sleep(float(os.environ.get(SLEEP_ENV, "0")))
    result = RunResult(kind="info", log_path=str(log_path), log_id=log_id, extra={"info": summary},
                       config_hash=config_hash(cfg),
                       metrics=[Metric(name="duration_s", value=summary["duration_s"], unit="s", group="info"),
                                Metric(name="messages", value=sum(t["count"] for t in summary["topics"]), unit="",
                                       group="info"),
                                Metric(name="topics", value=len(summary["topics"]), unit="", group="info")])
    write_result(result, work_dir / "info", dump_config(cfg))
    write_report([result], work_dir, gates=cfg.gates, config_text=dump_config(cfg), pdf=pdf)
    return Analysis(metrics=[(f"{m.group}/{m.name}", m.value, m.unit) for m in result.metrics], gates_failed=[])


def crashing_analysis(log_path: Path, cfg: Config, work_dir: Path, log_id: str, pdf: bool) -> Analysis:
    """A native crash (SIGABRT) in logs whose name contains "crash"."""
    if "crash" in log_path.name:
        os.abort()
    return info_analysis(log_path, cfg, work_dir, log_id, pdf)


def gated_analysis(log_path: Path, cfg: Config, work_dir: Path, log_id: str, pdf: bool) -> Analysis:
    """The info analysis, with the APE gate failed for logs named l1."""
    outcome = info_analysis(log_path, cfg, work_dir, log_id, pdf)
    if log_id == "l1":
        outcome.gates_failed.append("APE RMSE")
    return outcome


RTF_ENV = "MRNC_TEST_RTF"
RATE_ENV = "MRNC_TEST_MAPPING_RATE_HZ"


def rtf_analysis(log_path: Path, cfg: Config, work_dir: Path, log_id: str, pdf: bool) -> Analysis:
    """The info analysis plus a SLAM real-time factor (a wall-clock metric) and the mapping rate it was
    measured at, taken from the environment."""
    outcome = info_analysis(log_path, cfg, work_dir, log_id, pdf)
    outcome.metrics.append(("slam/rtf", float(os.environ[RTF_ENV]), ""))
    outcome.metrics.append(("slam/mapping_rate_hz", float(os.environ.get(RATE_ENV, "5.0")), "Hz"))
    return outcome
