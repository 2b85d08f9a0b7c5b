"""`mrnc-eval table`: the paper's Table I layout (APE RMSE in m, sequences x methods, Failed cells,
mean row, best marked) from one of three sources:

- a folder of `slam` results (`results/`, a nightly report root): one row per log, one column per
  method; each run's trajectory named by `slam.table_trajectory` against the ground truth the run
  found (recorded in its result.json); the newest run of each log and method;
- a folder of sequence folders: `<seq>/<method>.tum` beside `<seq>/ground_truth.tum`;
- a YAML manifest (MANIFEST_HELP).

References and estimates are trajectory specs as `ape` reads them (io/trajectory_inputs.py).
"""

from __future__ import annotations

import logging
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mrnc_eval.config import Config, load_yaml_file
from mrnc_eval.data import Trajectory
from mrnc_eval.errors import ConfigError, EvaluationError, InputError, UsageError
from mrnc_eval.evaluation.ape import ape
from mrnc_eval.evaluation.comparison import Cell, judge, table_one
from mrnc_eval.evaluation.modes import AlignMode
from mrnc_eval.io.ground_truth import gt_tum_path
from mrnc_eval.io.trajectory_files import read_trajectory
from mrnc_eval.io.trajectory_inputs import TrajectorySpec, parse_trajectory_spec
from mrnc_eval.outputs import claim_output, write_output
from mrnc_eval.reports.tables import SUFFIX_FORMAT, render_table
from mrnc_eval.results import RESULT_FILE, RunResult, read_result
from mrnc_eval.schema import slam as slam_keys
from mrnc_eval.tables import Table

log = logging.getLogger(__name__)

# slam.table_trajectory -> the file of a slam result folder that holds that trajectory
RUN_TRAJECTORY = {"online": "trajectory_online.tum", "smoothed": "trajectory.tum"}
SEQUENCE_REFERENCES = ("ground_truth.tum", "gt.tum")
MANIFEST_HELP = ("sequences: {NAME: {reference: REF, methods: {METHOD: EST, ...}}, ...} where REF and EST are "
                 "TUM, KITTI or EuRoC files, slam result folders or log.bag:/topic, relative to the manifest")


@dataclass(frozen=True, kw_only=True)
class Sequence:
    """One row: its reference and each method's estimate (None: the method gave none, Failed; a
    method missing from `methods` was not run on it)."""

    reference: TrajectorySpec
    methods: dict[str, TrajectorySpec | None]


def collect(source: Path, table_trajectory: str) -> dict[str, Sequence]:
    """The rows of the table from a results folder, a folder of sequence folders or a manifest."""
    if not source.exists():
        raise InputError(source, "no such file or folder")
    if not source.is_dir():
        return _from_manifest(source, table_trajectory)
    runs = _slam_runs(source)
    if runs:
        return _from_runs(runs, table_trajectory)
    sequences = _from_sequence_folders(source)
    if not sequences:
        raise InputError(source, "no slam result folders (result.json) and no sequence folders "
                                 f"(<seq>/ground_truth.tum) in it; or pass a YAML manifest ({MANIFEST_HELP})")
    return sequences


# ------------------------------------------------------------------ slam result folders


def _slam_runs(root: Path) -> list[tuple[Path, RunResult]]:
    """Every slam result folder at or under `root`. Links are not followed (`latest` points at a
    run already counted) and hidden folders (a result being written) are skipped."""
    runs = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        if RESULT_FILE in filenames:
            dirnames[:] = []  # a result folder holds no further runs
            result = read_result(dirpath, with_series=False)
            if result.kind == "slam":
                runs.append((Path(dirpath), result))
    return runs


def _run_reference(result: RunResult) -> TrajectorySpec | None:
    """The ground truth the run found: recorded in result.json (`extra.ground_truth`); for runs
    written before it was recorded, the same rule again from the log's path and roles."""
    if slam_keys.GROUND_TRUTH in result.extra:
        spec = result.extra[slam_keys.GROUND_TRUTH]
        return None if spec is None else parse_trajectory_spec(spec)
    topic = result.extra.get(slam_keys.ROLES, {}).get("ground_truth")
    if topic:
        return TrajectorySpec(result.log_path, topic)
    beside = gt_tum_path(Path(result.log_path))
    return TrajectorySpec(str(beside)) if beside.is_file() else None


def _log_key(result: RunResult, run_dir: Path) -> str:
    """What identifies a log: its path as recorded (absolute since issue 26; an older relative
    one is taken relative to the result folder's parent, the usual working folder)."""
    path = Path(result.log_path)
    return os.path.normpath(path if path.is_absolute() else run_dir.parent.parent / path)


def row_labels(paths: list[str]) -> dict[str, str]:
    """A short, distinct label per log path: the file name without suffix, with as many parent
    folders as needed to tell logs of one name apart ("day1/run", "day2/run")."""
    from mrnc_eval.results import log_id_for

    labels: dict[str, str] = {}
    for path in paths:
        parts = Path(path).parts
        depth = 1
        while True:
            label = "/".join([*parts[-depth:-1], log_id_for(parts[-1])]) if depth > 1 else log_id_for(parts[-1])
            clash = [p for p in paths if p != path and
                     "/".join([*Path(p).parts[-depth:-1], log_id_for(Path(p).name)]) == label]
            if not clash or depth >= len(parts):
                labels[path] = label
                break
            depth += 1
    return labels


def _from_runs(runs: list[tuple[Path, RunResult]], table_trajectory: str) -> dict[str, Sequence]:
    """One row per log path (as `slam` writes one row per log), one column per method: the newest
    run of each; runs that found no ground truth are left out with a warning (no APE to show)."""
    newest: dict[tuple[str, str], tuple[Path, RunResult]] = {}
    for run_dir, result in sorted(runs, key=lambda run: (run[1].created_utc, run[0].name)):
        newest[(_log_key(result, run_dir), str(result.extra.get(slam_keys.METHOD, "lio")))] = (run_dir, result)
    if len(newest) < len(runs):
        log.warning("%d older run(s) of a log and method left out: the table shows the newest of each",
                    len(runs) - len(newest))
    labels = row_labels(sorted({key for key, _m in newest}))
    sequences: dict[str, Sequence] = {}
    for (key, method), (run_dir, result) in sorted(newest.items(), key=lambda kv: (labels[kv[0][0]], kv[0][1])):
        reference = _run_reference(result)
        if reference is None:
            log.warning("%s: the run found no ground truth (no topic, no <log>.gt.tum); left out", run_dir)
            continue
        sequences.setdefault(labels[key], Sequence(reference=reference, methods={})).methods[method] = \
            TrajectorySpec(str(run_dir / RUN_TRAJECTORY[table_trajectory]))
    if not sequences:
        raise InputError(runs[0][0].parent, "no slam run in it found ground truth: nothing to tabulate")
    return sequences


# ------------------------------------------------------------------ sequence folders and manifests


def _from_sequence_folders(root: Path) -> dict[str, Sequence]:
    sequences = {}
    for seq_dir in sorted(p for p in root.iterdir() if p.is_dir()):
        gt = next((seq_dir / n for n in SEQUENCE_REFERENCES if (seq_dir / n).exists()), None)
        if gt is None:
            log.warning("%s: no ground_truth.tum, skipped", seq_dir)
            continue
        methods: dict[str, TrajectorySpec | None] = {
            p.stem: TrajectorySpec(str(p)) for p in sorted(seq_dir.glob("*.tum")) if p != gt}
        sequences[seq_dir.name] = Sequence(reference=TrajectorySpec(str(gt)), methods=methods)
    return sequences


def _from_manifest(path: Path, table_trajectory: str) -> dict[str, Sequence]:
    try:
        data = load_yaml_file(path, "manifest")
    except ConfigError as err:  # a manifest is an input, not configuration: exit 4 like any unreadable input
        raise InputError(path, str(err).removeprefix(f"{path}: ")) from err
    if not isinstance(data, dict) or not isinstance(data.get("sequences"), dict):
        raise InputError(path, f"a manifest needs a 'sequences' mapping: {MANIFEST_HELP}")
    base = path.parent

    def spec(text: Any) -> TrajectorySpec:
        parsed = parse_trajectory_spec(str(text), base=base)
        run = Path(parsed.path)
        if parsed.topic is None and (run / RESULT_FILE).is_file():  # a slam result folder: as for a results folder
            return TrajectorySpec(str(run / RUN_TRAJECTORY[table_trajectory]))
        return parsed

    sequences = {}
    for name, entry in data["sequences"].items():
        if not isinstance(entry, dict) or entry.get("reference") is None:
            raise InputError(path, f"sequence {name!r} needs a 'reference' ({MANIFEST_HELP})")
        methods = entry.get("methods") or {}
        if not isinstance(methods, dict):
            raise InputError(path, f"sequence {name!r}: 'methods' must map method names to trajectories")
        sequences[str(name)] = Sequence(reference=spec(entry["reference"]),
                                        methods={str(m): None if est is None else spec(est)
                                                 for m, est in methods.items()})
    return sequences


# ------------------------------------------------------------------ the table


def _cell(reference: Trajectory, seq: Sequence, method: str, cfg: Config, align: AlignMode) -> Cell:
    if method not in seq.methods:
        return Cell(None, not_run=True)
    estimate = seq.methods[method]
    if estimate is None or not estimate.exists():
        return Cell(None, "no trajectory")
    ev = cfg.evaluation
    try:
        r = ape(reference, read_trajectory(estimate), align=align, max_diff=ev.max_diff_s)
    except (EvaluationError, InputError) as err:
        return Cell(None, str(err))
    return judge(r.stats["rmse"], r.n, r.span_s, r.ref_span_s, min_matches=ev.failed_min_matches,
                 min_span_fraction=ev.failed_min_span_fraction)


def build_table_one(source: Path, cfg: Config | None = None, *, align: AlignMode = AlignMode.se3) -> Table:
    """Table I from `source`; APE after `align` alignment with the association and Failed rules
    of cfg.evaluation."""
    cfg = cfg or Config()
    sequences = collect(source, cfg.slam.table_trajectory)
    methods = sorted({m for seq in sequences.values() for m in seq.methods})
    cells = {}
    for name, seq in sequences.items():
        reference = read_trajectory(seq.reference)
        for m in methods:
            cells[(name, m)] = _cell(reference, seq, m, cfg, align)
    table = table_one(cells, list(sequences), methods)
    ev = cfg.evaluation
    table.notes.append("not run: the method was never run on that log (no result, no file); "
                       "Failed: no trajectory, an evaluation error, "
                       f"fewer than {ev.failed_min_matches} matched poses, "
                       f"or a matched span under {ev.failed_min_span_fraction:.0%} of the reference's; "
                       f"APE after {align} alignment, max_diff {ev.max_diff_s} s")
    if any(spec is not None and Path(spec.path).name == RUN_TRAJECTORY[cfg.slam.table_trajectory]
           for seq in sequences.values() for spec in seq.methods.values()):
        table.notes.append(f"slam runs: {RUN_TRAJECTORY[cfg.slam.table_trajectory]} (slam.table_trajectory="
                           f"{cfg.slam.table_trajectory}) against the ground truth each run found")
    return table


def table_items(table: Table) -> list[dict[str, Any]]:
    """One --json `results` item per cell: sequence, method, its number (null when Failed) and
    why it failed; the mean row is a sequence named "Mean" like in the table."""
    from mrnc_eval.commands.output import is_stat, item

    out = []
    for row, cells in zip(table.row_labels, table.cells, strict=True):
        for column, cell in zip(table.column_labels, cells, strict=True):
            number = cell if is_stat(cell) else None
            out.append(item(f"{row}/{column}", {"value": number}, sequence=row, method=column,
                            failed=None if number is not None else str(cell or "no value")))
    return out


def main(source: Path, cfg: Config, *, out: Path | None, align: AlignMode, json_out: bool, force: bool = False
         ) -> None:
    """The `table` verb: Markdown on stdout, JSON with --json, a file by suffix with --out."""
    from mrnc_eval.commands.output import emit_json

    fmt = SUFFIX_FORMAT.get(out.suffix.lower()) if out is not None else "markdown"
    if fmt is None:
        raise UsageError(f"--out {out}: use a .md, .tex, .csv or .html file")
    if out is not None:
        claim_output(out, force=force, inputs=[source])
    table = build_table_one(source, cfg, align=align)  # everything computed before anything is written
    if json_out:
        emit_json("table", table_items(table), meta={"table": table.__dict__})
    elif out is None:
        sys.stdout.write(render_table(table, "markdown"))
    if out is not None:
        write_output(out, render_table(table, fmt), force=force, inputs=[source])
