"""`mrnc-eval report RESULT_DIR...`: HTML (and PDF) from result directories."""

from __future__ import annotations

import sys
from pathlib import Path

from mrnc_eval.config import CONFIG_FILE_NAME, load_config
from mrnc_eval.results import read_result


def main(result_dirs: list[Path], *, out: Path | None, pdf: bool) -> None:
    from mrnc_eval.reports.render import write_report

    results = [read_result(d) for d in result_dirs]
    config_path = result_dirs[0] / CONFIG_FILE_NAME
    config_text = config_path.read_text(encoding="utf-8") if config_path.exists() else ""
    cfg = load_config(config_path) if config_path.exists() else load_config()
    target = out or result_dirs[0]
    written = write_report(results, target, gates=cfg.gates, config_text=config_text, pdf=pdf)
    for kind, path in written.items():
        sys.stdout.write(f"{kind}: {path}\n")
