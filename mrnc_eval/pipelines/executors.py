"""Where the logs of a night run: in this process, in a local pool of subprocesses (one per
log, so a native crash in one log cannot take the batch down), or on a Dask cluster.
All three take (log, config YAML, out dir, pdf) jobs and yield summaries as they finish."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

from mrnc_eval.pipelines.log_job import process_log

Job = tuple[str, str, str, bool]  # log path, config YAML, output dir, pdf


def run_in_process(jobs: list[Job]) -> Iterator[dict]:
    for job in jobs:
        yield process_log(*job)


def run_local_pool(jobs: list[Job], workers: int) -> Iterator[dict]:
    tmp = Path(tempfile.mkdtemp(prefix="mrnc-nightly-"))

    def one(k: int, job: Job) -> dict:
        log, cfg_yaml, out, pdf = job
        cfg_file, summary = tmp / f"{k}.yaml", tmp / f"{k}.json"
        cfg_file.write_text(cfg_yaml, encoding="utf-8")
        env = {**os.environ, "PYTHONHASHSEED": "0"}
        proc = subprocess.run([sys.executable, "-m", "mrnc_eval.pipelines.log_job", log, str(cfg_file), out,
                               "1" if pdf else "0", str(summary)], capture_output=True, text=True, env=env)
        if summary.exists():
            return json.loads(summary.read_text(encoding="utf-8"))
        from mrnc_eval.results import log_id_for

        return {"log_id": log_id_for(log), "log_path": log, "status": "failed", "metrics": [], "gates_failed": [],
                "report": "", "config_hash": "", "tool_version": "", "run_id": "",
                "error": f"worker process died (exit code {proc.returncode}): {proc.stderr.strip()[-300:]}"}

    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        futures = [pool.submit(one, k, job) for k, job in enumerate(jobs)]
        for fut in as_completed(futures):
            yield fut.result()


def run_dask(jobs: list[Job], scheduler: str) -> Iterator[dict]:
    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
    except ImportError as err:
        from mrnc_eval.errors import UsageError

        raise UsageError("--scheduler needs the dask extra: pip install 'mrnc-eval[dask]'") from err
    with Client(scheduler, timeout="30s") as client:
        futures = [client.submit(process_log, *job, pure=False, key=f"mrnc-{k}") for k, job in enumerate(jobs)]
        for fut in dask_completed(futures):
            yield fut.result()
