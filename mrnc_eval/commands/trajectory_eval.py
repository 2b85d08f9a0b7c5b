"""CLI glue of `ape` and `rpe`: read trajectories, evaluate, print, write (`table`: commands/table.py)."""

from __future__ import annotations

import logging
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mrnc_eval.data import Trajectory
from mrnc_eval.errors import UsageError
from mrnc_eval.evaluation.ape import ApeResult, ape
from mrnc_eval.evaluation.decompose import Decomposition
from mrnc_eval.evaluation.drift import DriftResult
from mrnc_eval.evaluation.modes import AlignMode, DeltaUnit, PairsFrom, Relation, SyncMethod
from mrnc_eval.evaluation.relations import TITLES
from mrnc_eval.evaluation.rpe import RpeResult, rpe
from mrnc_eval.io.trajectory_files import is_kitti_file, read_trajectory
from mrnc_eval.outputs import claim_output, output_file, write_output
from mrnc_eval.reports.tables import SUFFIX_FORMAT, render_table
from mrnc_eval.tables import Cell as CellValue
from mrnc_eval.tables import Table
from mrnc_eval.text import printable

if TYPE_CHECKING:
    import numpy as np
    from matplotlib.figure import Figure

Results = Sequence[ApeResult] | Sequence[RpeResult]

log = logging.getLogger(__name__)
STAT_ORDER = ("rmse", "mean", "median", "std", "min", "max", "sse")
PLOT_SUFFIXES = (".svg", ".png", ".pdf")


def _results_table(results: Results, title: str) -> Table:
    return Table(title=title, row_labels=[printable(r.name) for r in results],  # file names: one line each
                 column_labels=[*STAT_ORDER, "n", "span_s"],
                 cells=[[*(r.stats[k] for k in STAT_ORDER), r.n, round(r.span_s, 3)] for r in results],
                 unit=results[0].unit, best=None, precision=6)


def _claim_outputs(table: Path | None, plot: Path | None, specs: list[str], force: bool,
                   save_results: Path | None = None) -> list[Path]:
    """Before any work: the suffixes, and the one overwrite rule for --table, --plot and
    --save_results (never one of the trajectories read). Returns the input files."""
    if table is not None and SUFFIX_FORMAT.get(table.suffix.lower()) is None:
        raise UsageError(f"--table {table}: use a .md, .tex, .csv or .html file")
    if plot is not None and plot.suffix.lower() not in PLOT_SUFFIXES:
        raise UsageError(f"--plot {plot}: use a {', '.join(PLOT_SUFFIXES)} file")
    if save_results is not None:
        if save_results.suffix.lower() != ".zip":
            raise UsageError(f"--save_results {save_results}: evo's result file is a .zip")
        if len(specs) != 2:
            raise UsageError(f"--save_results holds one result (as evo's); got {len(specs) - 1} estimates")
    inputs = [Path(s.split(":/", 1)[0]) for s in specs]  # log.bag:/topic reads log.bag
    for target in (table, plot, save_results):
        if target is not None:
            claim_output(target, force=force, inputs=inputs)
    return inputs


def _emit(results: Results, title: str, json_out: bool, table: Path | None, plot: Path | None,
          drifts: list[DriftResult] | None = None, decompositions: list[Decomposition] | None = None,
          force: bool = False, inputs: list[Path] | None = None, plot_mode: str | None = None,
          save_results: Path | None = None, evo_names: tuple[str, str] | None = None,
          evo_title: dict[str, Any] | None = None) -> None:
    """Print (JSON or Markdown), then write the table, plot and evo zip files; all computed before."""
    from mrnc_eval.commands.output import emit_json

    inputs = inputs or []
    if json_out:
        emit_json("ape" if isinstance(results[0], ApeResult) else "rpe", _summaries(results, drifts, decompositions),
                  meta={"title": title})
    else:
        sys.stdout.write(render_table(_results_table(results, title), "markdown"))
        if drifts is not None:
            sys.stdout.write("\n" + render_table(_drift_table([r.name for r in results], drifts), "markdown"))
        if decompositions is not None:
            sys.stdout.write("\n" + render_table(_decomposition_table([r.name for r in results], decompositions),
                                                 "markdown"))
    if table is not None:
        write_output(table, render_table(_results_table(results, title), SUFFIX_FORMAT[table.suffix.lower()]),
                     force=force, inputs=inputs)
    apes = [r for r in results if isinstance(r, ApeResult)]
    if plot is not None and len(apes) == len(results):
        _save_figure(_path_figure(apes, title, _plot_axes(plot_mode)), plot, force, inputs)
    elif plot is not None:
        _save_figure(_error_figure(results, title), plot, force, inputs)
    if save_results is not None:
        from mrnc_eval.io.evo_results import evo_result, evo_zip_bytes

        ref_name, est_name = evo_names or ("reference", results[0].name)
        write_output(save_results, evo_zip_bytes(evo_result(results[0], ref_name=ref_name, est_name=est_name,
                                                            **(evo_title or {}))), force=force, inputs=inputs)


def _plot_axes(plot_mode: str | None) -> str:
    """evo's --plot_mode as the two axes drawn; xyz (a 3-D view) is drawn as xy, with a note."""
    if plot_mode is None:
        return "xy"
    if len(plot_mode) != 2:
        sys.stderr.write(f"note: --plot_mode {plot_mode}: the path plot is 2-D; drawn in xy\n")
        return "xy"
    return plot_mode


def _summaries(results: Results, drifts: list[DriftResult] | None,
               decompositions: list[Decomposition] | None) -> list[dict[str, Any]]:
    """One `results` item per estimate: the statistics, n and span under `stats`, the matching
    counts, the alignment used (mode, poses, scale, 4x4), drift and decomposition beside them
    (commands/output.py)."""
    from mrnc_eval.commands.output import item, split_stats

    summaries = []
    for r in results:
        flat = r.summary()
        name = str(flat.pop("name"))
        stats, rest = split_stats(flat)
        summaries.append(item(name, stats, unit=r.unit, alignment=r.alignment_summary(), **rest))
    extras: dict[str, Sequence[DriftResult | Decomposition] | None] = {"drift": drifts, "decomposition": decompositions}
    for key, extra in extras.items():
        if extra is not None:
            for s, x in zip(summaries, extra, strict=True):
                s[key] = x.summary()
    return summaries


def _decomposition_table(names: list[str], decs: list[Decomposition]) -> Table:
    parts = (("along_m", "along-track (m)"), ("cross_m", "cross-track (m, + left)"), ("vertical_m", "vertical (m)"),
             ("yaw_deg", "yaw (deg)"))
    rows: list[str] = []
    cells: list[list[CellValue]] = []
    for name, dec in zip(names, decs, strict=True):
        summary = dec.summary()
        for key, label in parts:
            rows.append(f"{name} {label}")
            cells.append([summary[key][k] for k in STAT_ORDER[:-1]])
    return Table(title="APE decomposed: signed errors of the aligned estimate along and across the reference's "
                       "direction of travel, vertical, and in yaw", row_labels=rows,
                 column_labels=list(STAT_ORDER[:-1]), cells=cells, best=None, precision=4)


def _decimated_max(t: np.ndarray, e: np.ndarray, buckets: int = 10000) -> tuple[np.ndarray, np.ndarray]:
    """At most `buckets` points for a plot, each the largest error of its bucket, so peaks
    survive decimation (statistics always use every pose)."""
    import numpy as np

    if e.size <= buckets:
        return t, e
    starts = np.linspace(0, e.size, buckets, endpoint=False).astype(np.int64)
    return t[starts], np.maximum.reduceat(e, starts)


def _path_figure(results: Sequence[ApeResult], title: str, plot_axes: str = "xy") -> Figure:
    """Each estimate's aligned path coloured by its APE, the reference dashed beside it (the
    SLAM report's figure); statistics use every pose, the drawing is decimated."""
    from mrnc_eval.reports.figures import ape_path_figure

    return ape_path_figure(results, title, plot_axes)


def _error_figure(results: Results, title: str) -> Figure:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 3.5), layout="constrained")
    ax = fig.add_subplot()
    for r in results:
        t, e = _decimated_max(r.stamps - r.stamps[0], r.errors)
        ax.plot(t, e, lw=0.8, label=r.name)
    ax.set_xlabel("time since first match (s)")
    ax.set_ylabel(f"error ({results[0].unit})" if results[0].unit else "error")
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize="small")
    return fig


def _save_figure(fig: Figure, path: Path, force: bool, inputs: list[Path]) -> None:
    with output_file(path, force=force, inputs=inputs) as tmp:  # atomic: no half-written plot
        fig.savefig(tmp, format=path.suffix.lower().lstrip("."))


def _index_pairing(ref: str, est: str) -> bool:
    """KITTI files have no stamps: pair them by line, and only with each other."""
    ref_k, est_k = is_kitti_file(ref), is_kitti_file(est)
    if ref_k != est_k:
        kitti, other = (ref, est) if ref_k else (est, ref)
        raise UsageError(f"{kitti} is a KITTI pose file (no time stamps) but {other} is not: "
                         "KITTI files can only be paired line by line with another KITTI file")
    return ref_k


EVO_FORMAT_WORDS = ("tum", "kitti", "euroc", "bag", "bag2", "mcap")


def evo_positionals(ref: str, est: list[str]) -> tuple[str, list[str]]:
    """evo's positional form: `tum REF EST`, `kitti ...`, `euroc ...` drop the format word (the
    format is found from the file); `bag LOG REF_TOPIC EST_TOPIC...` become LOG:/topic specs. The
    word is taken as a format only when no file of that name exists. A note goes to stderr."""
    if ref not in EVO_FORMAT_WORDS or Path(ref).exists() or not est:
        return ref, est
    if ref in ("bag", "bag2", "mcap"):
        if len(est) < 3:
            raise UsageError(f"evo's form `{ref} LOG REF_TOPIC EST_TOPIC` needs a log and two topics")
        log_file, topics = est[0], est[1:]
        specs = [f"{log_file}:{t}" for t in topics]
        sys.stderr.write(f"note: evo's format word {ref!r} ignored; reading {', '.join(specs)}\n")
        return specs[0], specs[1:]
    if len(est) < 2:
        raise UsageError(f"evo's form `{ref} REF EST` needs a reference and an estimate")
    sys.stderr.write(f"note: evo's format word {ref!r} ignored; the format is found from each file\n")
    return est[0], est[1:]


SLAM_FILES = {"trajectory": "", "trajectory_online": " online"}  # slam's file stems -> label suffix


def default_label(spec: str, name: str) -> str:
    """An estimate's name in tables, plots and JSON: a slam result's folder name (the run) for
    a result folder or its trajectory files, else the name read_trajectory gave (file stem)."""
    path = Path(spec.rstrip("/"))
    if path.is_dir() and (path / "trajectory.tum").is_file():
        return path.resolve().name
    if path.is_file() and path.stem in SLAM_FILES:
        return path.parent.resolve().name + SLAM_FILES[path.stem]
    return name


def _load(ref: str, est: list[str], labels: list[str] | None = None) -> tuple[Any, list[tuple[Any, bool]]]:
    """The reference and each estimate (with its pairing mode), named by `labels` (one per
    estimate) or uniquely from their paths. Files are read in parallel threads (pandas' C
    tokenizer releases the GIL); the first error is raised as is."""
    from concurrent.futures import ThreadPoolExecutor

    if labels and len(labels) != len(est):
        raise UsageError(f"--label given {len(labels)} time(s) for {len(est)} estimate(s): give one per EST, "
                         "in the same order")
    pairing = [_index_pairing(ref, e) for e in est]
    with ThreadPoolExecutor(max_workers=min(4, 1 + len(est))) as pool:
        reference, *trajs = list(pool.map(read_trajectory, [ref, *est]))
    estimates = [(replace(t, name=labels[k] if labels else default_label(spec, t.name)), by_index)
                 for k, (t, by_index, spec) in enumerate(zip(trajs, pairing, est, strict=True))]
    log.info("reference %s: %d poses over %.2f s", ref, len(reference),
             float(reference.stamps[-1] - reference.stamps[0]) if len(reference) else 0.0)
    for spec, (t, by_index) in zip(est, estimates, strict=True):
        log.info("estimate %s: %d poses%s", spec, len(t), " (paired by line: KITTI)" if by_index else "")
    names = [t.name for t, _ in estimates]
    for k, ((t, by_index), spec) in enumerate(zip(estimates, est, strict=True)):
        if names.count(t.name) > 1 and not labels:  # same name from different folders: use the path
            estimates[k] = (replace(t, name=str(spec)), by_index)
    return reference, estimates


def parse_offset(text: str | float) -> float | None:
    """--offset: seconds added to the estimate's stamps, or "auto" (None) to estimate them."""
    if isinstance(text, (int, float)):
        return float(text)
    if text.strip().lower() == "auto":
        return None
    try:
        return float(text)
    except ValueError:
        raise UsageError(f"--offset must be a number of seconds or 'auto', got {text!r}") from None


def _offsets(reference: Trajectory, estimates: list[tuple[Trajectory, bool]], offset: str | float,
             align: AlignMode) -> list[float]:
    """The offset for each estimate; with 'auto', estimated and printed (stderr)."""
    fixed = parse_offset(offset)
    if fixed is not None:
        return [fixed] * len(estimates)
    from mrnc_eval.evaluation.offset import estimate_offset

    out = []
    for e, by_index in estimates:
        if by_index:
            raise UsageError("--offset auto needs time stamps; KITTI files are paired line by line")
        o = estimate_offset(reference, e, align=align)
        sys.stderr.write(f"{e.name}: estimated clock offset {o.offset_s:+.4f} s (added to its stamps; "
                         f"speed correlation {o.correlation:.2f}, aligned APE {o.rmse_m:.4f} m)\n")
        out.append(o.offset_s)
    return out


def _warn_stamps(ref: str, est: list[str], results: list[ApeResult] | list[RpeResult]) -> None:
    """One warning line per file with repeated or unsorted stamps (the reference once)."""
    seen = set()
    either: list[ApeResult | RpeResult] = list(results)
    sides = [(ref, r.matching.ref_counts) for r in either[:1]] + [
        (spec, r.matching.est_counts) for spec, r in zip(est, either, strict=True)]
    for spec, counts in sides:
        if spec in seen or not (counts.repeated or counts.unsorted):
            continue
        seen.add(spec)
        what = [f"{counts.repeated} repeated" if counts.repeated else "",
                f"{counts.unsorted} out-of-order" if counts.unsorted else ""]
        log.warning("%s: %s time stamp(s), paired as evo does (--strict refuses such files)",
                    spec, " and ".join(w for w in what if w))


def ape_main(ref: str, est: list[str], *, align: AlignMode, n_to_align: int | None, relation: Relation, max_diff: float,
             offset: str | float, plane: str | None, json_out: bool, table: Path | None, plot: Path | None,
             strict: bool = False, sync: SyncMethod = SyncMethod.nearest, max_gap: float = 0.2,
             decompose: bool = False, force: bool = False, plot_mode: str | None = None,
             save_results: Path | None = None, labels: list[str] | None = None) -> None:
    ref, est = evo_positionals(ref, est)
    inputs = _claim_outputs(table, plot, [ref, *est], force, save_results)
    reference, estimates = _load(ref, est, labels)
    offsets = _offsets(reference, estimates, offset, align)
    results = [ape(reference, e, align=align, n_to_align=n_to_align, relation=relation, max_diff=max_diff,
                   offset=o, plane=plane, by_index=by_index, strict=strict, sync=sync, max_gap=max_gap)
               for (e, by_index), o in zip(estimates, offsets, strict=True)]
    _warn_stamps(ref, est, results)
    for r in results:
        log.info("%s: %d matched poses over %.2f s, RMSE %.6g %s", r.name, r.n, r.span_s, r.stats["rmse"], r.unit)
    decompositions = [r.decompose() for r in results] if decompose else None
    title = f"APE w.r.t. {TITLES[relation]}, {alignment_phrase(results[0].alignment_summary())}"
    _emit(results, title, json_out, table, plot, decompositions=decompositions, force=force, inputs=inputs,
          plot_mode=plot_mode, save_results=save_results, evo_names=(ref, est[0]))


def alignment_phrase(a: dict[str, Any]) -> str:
    """The alignment in words, for the first line of every result (evo's default is none)."""
    words = {"none": "not aligned (evo's default; -a or --align se3 aligns)", "se3": "SE(3) Umeyama alignment",
             "sim3": "Sim(3) Umeyama alignment", "scale": "scale corrected (Umeyama scale only)",
             "origin": "origin alignment (first poses coincide)", "yaw": "4-DoF alignment (yaw + translation)"}
    phrase = "alignment: " + words[a["mode"]]
    if a["mode"] not in ("none", "origin") and a.get("n_to_align") is not None:
        phrase += f", on the first {a['n_to_align']} poses"
    return phrase


def rpe_main(ref: str, est: list[str], *, delta: float | None, delta_unit: DeltaUnit, all_pairs: bool, align: AlignMode,
             n_to_align: int | None, relation: Relation, max_diff: float, offset: str | float, plane: str | None,
             json_out: bool, table: Path | None, plot: Path | None, pairs_from: PairsFrom = PairsFrom.estimate,
             drift: bool = False, strict: bool = False, sync: SyncMethod = SyncMethod.nearest,
             max_gap: float = 0.2, force: bool = False, plot_mode: str | None = None,
             save_results: Path | None = None, labels: list[str] | None = None) -> None:
    ref, est = evo_positionals(ref, est)
    inputs = _claim_outputs(table, plot, [ref, *est], force, save_results)
    # the delta as evo titles it: frames as an integer, metres as typed (a float: "2.0"), its default the integer 1
    delta_text = "1" if delta is None else str(int(delta)) if delta_unit is DeltaUnit.frames and delta == int(delta) \
        else repr(float(delta))
    delta = 1.0 if delta is None else delta
    reference, estimates = _load(ref, est, labels)
    offsets = _offsets(reference, estimates, offset, align)
    results = [rpe(reference, e, delta=delta, delta_unit=delta_unit, all_pairs=all_pairs, align=align,
                   n_to_align=n_to_align, relation=relation, max_diff=max_diff, offset=o, plane=plane,
                   pairs_from=pairs_from, by_index=by_index, strict=strict, sync=sync, max_gap=max_gap)
               for (e, by_index), o in zip(estimates, offsets, strict=True)]
    _warn_stamps(ref, est, results)
    drifts = None
    if drift:
        from mrnc_eval.evaluation.drift import drift as kitti_drift

        drifts = [kitti_drift(reference, e, align=align, max_diff=max_diff, offset=o, by_index=by_index)
                  for (e, by_index), o in zip(estimates, offsets, strict=True)]
    title = (f"RPE w.r.t. {TITLES[relation]}, delta {delta:g} {delta_unit}"
             f"{', all pairs' if all_pairs else ''} (pairs from the {pairs_from}), "
             f"{alignment_phrase(results[0].alignment_summary())}")
    _emit(results, title, json_out, table, plot, drifts=drifts, force=force, inputs=inputs, plot_mode=plot_mode,
          save_results=save_results, evo_names=(ref, est[0]),
          evo_title={"all_pairs": all_pairs, "delta_text": delta_text})


def _drift_table(names: list[str], drifts: list[DriftResult]) -> Table:
    lengths = drifts[0].lengths_m
    cols = [f"{L:g} m" for L in lengths] + ["mean"]
    trans: list[list[CellValue]] = [[*(d.trans_pct.get(L, "n/a") for L in lengths), d.mean_trans_pct] for d in drifts]
    rot: list[list[CellValue]] = [[*(d.rot_deg_per_m.get(L, "n/a") for L in lengths), d.mean_rot_deg_per_m]
                                  for d in drifts]
    return Table(title="KITTI drift: translation (%) / rotation (deg/m) over segments of the reference path",
                 row_labels=[f"{n} t%" for n in names] + [f"{n} deg/m" for n in names], column_labels=cols,
                 cells=trans + rot, best=None, precision=4,
                 notes=[f"{n}: {d.n_segments} segments, reference path {d.path_length_m:.1f} m"
                        for n, d in zip(names, drifts, strict=True)])
