"""One log of the nightly job: info, SLAM, control replay, report. Runs in a worker process
(a subprocess of the local pool, or a Dask worker) and returns a plain, picklable summary."""

from __future__ import annotations

import datetime as dt
import json
import shutil
import sys
import traceback
from pathlib import Path

from mrnc_eval import __version__


def process_log(log_path: str, config_yaml: str, out_dir: str, pdf: bool = True) -> dict:
    """Never raises: a failure becomes a summary with status "failed" and the error text."""
    import yaml

    from mrnc_eval.config import Config, build, config_hash, dump_config
    from mrnc_eval.errors import MrncError
    from mrnc_eval.results import log_id_for

    cfg = build(Config, yaml.safe_load(config_yaml) or {})
    log_id = log_id_for(log_path)
    target = Path(out_dir)
    partial = target.with_name(f".{target.name}.partial")
    summary = {"log_id": log_id, "log_path": log_path, "status": "failed", "error": "", "metrics": [],
               "gates_failed": [], "report": "", "config_hash": config_hash(cfg), "tool_version": __version__,
               "run_id": f"{log_id}-{dt.datetime.now(dt.UTC).strftime('%Y%m%dT%H%M%SZ')}"}
    try:
        from mrnc_eval.pipelines import control, info, slam
        from mrnc_eval.reports.render import evaluate_gates, write_report

        shutil.rmtree(partial, ignore_errors=True)
        partial.mkdir(parents=True)
        summary_info = info.run(Path(log_path), cfg).to_json()
        results = [slam.run_log(Path(log_path), cfg, partial / "slam")]
        if all(r in summary_info["roles"] for r in ("path", "wheel_speeds")):
            results.append(control.run_log(Path(log_path), cfg, partial / "control", mode="replay"))
        write_report(results, partial, gates=cfg.gates, config_text=dump_config(cfg), info=summary_info, pdf=pdf)
        gates = evaluate_gates(results, cfg.gates)
        summary["gates_failed"] = [g.label for g in gates if g.status == "fail"]
        summary["metrics"] = [(f"{m.group}/{m.name}", _num(m.value), m.unit) for r in results for m in r.metrics]
        if target.exists():
            shutil.rmtree(target)
        partial.replace(target)
        summary["report"] = str(target / "report.html")
        summary["status"] = "ok"
    except MrncError as err:
        summary["error"] = str(err)
    except Exception as err:  # noqa: BLE001 - one log's bug must not end the night; keep the traceback
        summary["error"] = f"{type(err).__name__}: {err}"
        summary["traceback"] = traceback.format_exc()
    finally:
        shutil.rmtree(partial, ignore_errors=True)
    return summary


def _num(v):
    import math

    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return None
    return float(v)


if __name__ == "__main__":  # python -m mrnc_eval.pipelines.log_job LOG CONFIG_YAML_FILE OUT_DIR PDF SUMMARY_JSON
    log, cfg_file, out, pdf, summary_file = sys.argv[1:6]
    result = process_log(log, Path(cfg_file).read_text(encoding="utf-8"), out, pdf == "1")
    tmp = Path(summary_file + ".tmp")
    tmp.write_text(json.dumps(result), encoding="utf-8")
    tmp.replace(summary_file)
