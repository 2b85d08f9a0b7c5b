"""`mrnc-eval report RESULT_DIR...`: HTML (and PDF, CSV/LaTeX tables) from result directories.

A RESULT_DIR is a result directory (slam, control, info) or a folder holding some, such as a
nightly per-log folder; reports are rendered from the results only, never recomputed."""

from __future__ import annotations

import sys
from pathlib import Path

from mrnc_eval.commands.gates import raise_on_failed_gates
from mrnc_eval.config import CONFIG_FILE_NAME, load_config
from mrnc_eval.errors import InputError
from mrnc_eval.outputs import claim_output
from mrnc_eval.results import RESULT_FILE, RunResult, read_result

KIND_ORDER = {"info": 0, "slam": 1, "control": 2}


def result_dirs_of(paths: list[Path]) -> list[Path]:
    """Result directories given directly, or the result directories one level below a folder."""
    found: list[Path] = []
    for p in paths:
        if (p / RESULT_FILE).is_file():
            found.append(p)
        elif p.is_dir() and (subs := sorted(d for d in p.iterdir() if (d / RESULT_FILE).is_file()
                                            and not d.is_symlink())):  # OUT/latest repeats a run
            found += subs
        else:
            raise InputError(p, f"not a result directory (no {RESULT_FILE} in it or in its sub-folders)")
    return found


def configs_of(dirs: list[Path], results: list[RunResult]) -> dict[str, str]:
    """Configuration hash -> the config.yaml of a result that ran with it (every distinct one)."""
    by_dir = {str(Path(d).resolve()): d for d in dirs}
    out: dict[str, str] = {}
    for d in by_dir.values():
        r = read_result(d, with_series=False)
        if r.config_hash and r.config_hash not in out and (d / CONFIG_FILE_NAME).is_file():
            out[r.config_hash] = (d / CONFIG_FILE_NAME).read_text(encoding="utf-8")
    order = [r.config_hash for r in results]
    return dict(sorted(out.items(), key=lambda kv: order.index(kv[0]) if kv[0] in order else len(order)))


def main(result_dirs: list[Path], *, out: Path | None, pdf: bool, junit: Path | None = None,
         force: bool = False, appendix_config: bool = False) -> None:
    from mrnc_eval.reports.render import write_report

    dirs = result_dirs_of(result_dirs)
    results: list[RunResult] = sorted((read_result(d) for d in dirs), key=lambda r: KIND_ORDER.get(r.kind, 9))
    logs = sorted({str(Path(r.log_path).resolve()) for r in results})
    if len(logs) > 1:
        raise InputError(result_dirs[0], f"results of different logs ({', '.join(logs)}); one log per report")
    config_path = next((d / CONFIG_FILE_NAME for d in dirs if (d / CONFIG_FILE_NAME).is_file()), None)
    config_text = config_path.read_text(encoding="utf-8") if config_path else ""
    cfg = load_config(config_path) if config_path else load_config()
    configs = configs_of(dirs, results)
    target = out or (result_dirs[0] if len(dirs) > 1 or not (result_dirs[0] / RESULT_FILE).is_file() else dirs[0])
    if junit is not None:
        claim_output(junit, force=force, inputs=dirs)  # before anything is written
    written = write_report(results, target, gates=cfg.gates, config_text=config_text, pdf=pdf, force=force,
                           configs=configs or None, appendix_config=appendix_config)
    if junit is not None:
        from mrnc_eval.reports.junit import suite_of_results, write_junit

        suite = suite_of_results(results[0].log_id, results[0].log_path, results, cfg.gates, (cfg.slam.method,))
        write_junit(junit, [suite], f"mrnc-eval report {results[0].log_id}", force=force)
        written["junit"] = junit
    for kind, path in written.items():
        sys.stdout.write(f"{kind}: {path}\n")
    raise_on_failed_gates(results, cfg.gates)
