"""Command line: one thin command per verb. It parses, calls a command module and maps errors
to exit codes in `main()` (the only place that does). No algorithm lives here.

Heavy modules (open3d, gtsam, matplotlib, weasyprint, dask) are imported inside the
command modules, so `mrnc-eval --help` stays instant.
"""

from __future__ import annotations

import errno
import logging
import sys
from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any

import typer
from typer.exceptions import TyperException

from mrnc_eval import __version__
from mrnc_eval.cli_fast import fast_command
from mrnc_eval.cli_help import PlainGroup
from mrnc_eval.errors import Interrupted, MrncError, UsageError, forget_interrupt, interrupt, raise_if_interrupted
from mrnc_eval.evaluation.modes import AlignMode, DeltaUnit, PairsFrom, Relation, SyncMethod
from mrnc_eval.text import install_log_format, printable

__all__ = ["app", "main", "printable"]

log = logging.getLogger("mrnc_eval")

app = typer.Typer(
    name="mrnc-eval",
    help="Offline log processing and evaluation for skid-steer wheeled mobile robots (SSWMR) "
    "(LIO-SAM-style SLAM replay, pure pursuit + RAID control replay, APE/RPE, HTML/PDF reports). "
    "Global options (--debug, -v, -q) may also follow the verb.",
    cls=PlainGroup,
    no_args_is_help=True,
    add_completion=True,  # --install-completion, --show-completion (bash, zsh, fish, PowerShell)
    pretty_exceptions_enable=False,
    rich_markup_mode="rich",  # markdown would eat <run>, <date>, <seq>/<method> as HTML tags
    context_settings={"help_option_names": ["-h", "--help"]},
)

_state: dict[str, Any] = {"debug": False}

# ------------------------------------------------------------------ shared options

ConfigOpt = Annotated[
    Path | None,
    typer.Option("--config", "-c", help="YAML configuration (safe-loaded); defaults: mrnc-eval config."),
]
SetOpt = Annotated[
    list[str] | None,
    typer.Option("--set", metavar="KEY=VALUE",
                 help="Override one parameter, e.g. --set control.raid.beta=1.5 (repeatable)."),
]
DumpOpt = Annotated[
    bool, typer.Option("--dump-config", help="Print the effective configuration as YAML and exit.")
]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print machine-readable JSON to stdout.")]
ForceOpt = Annotated[bool, typer.Option(
    "--force", help="Replace an existing output file, only one this tool wrote (never an input).")]
JunitOpt = Annotated[Path | None, typer.Option(
    help="Also write the metric gates as JUnit XML (one test case per gate per log) for CI.")]


def _plain(choice: StrEnum | None) -> str | None:
    """A choice as the plain str the commands expect (YAML's safe dumper refuses str subclasses)."""
    return None if choice is None else choice.value


def _config(path: Path | None, overrides: list[str] | None, dump: bool = False):  # -> Config
    from mrnc_eval.config import dump_config, load_config

    cfg = load_config(path, overrides or ())
    if dump:
        sys.stdout.write(dump_config(cfg))
        raise typer.Exit(0)
    return cfg


# ------------------------------------------------------------------ global callback


def _version(value: bool) -> None:
    if value:
        sys.stdout.write(f"mrnc-eval {__version__}\n")
        raise typer.Exit(0)


@app.callback()
def _main(
    verbose: Annotated[
        int,
        typer.Option("--verbose", "-v", count=True, help="More log output on stderr (-vv: debug)."),
    ] = 0,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Only errors on stderr.")] = False,
    debug: Annotated[bool, typer.Option("--debug", help="Show tracebacks for errors.")] = False,
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version and exit."),
    ] = False,
) -> None:
    chatty = (logging.WARNING, logging.INFO, logging.DEBUG)[min(verbose + (1 if debug else 0), 2)]
    level = logging.ERROR if quiet else chatty
    install_log_format(level, sys.stderr)  # every message escaped (text.PrintableFormatter)
    _state["debug"] = debug


# ------------------------------------------------------------------ verbs


@app.command()
def config(
    key: Annotated[str | None, typer.Argument(metavar="KEY", help="Only this subtree or value: slam.loop.")] = None,
    config: ConfigOpt = None,
    set_: SetOpt = None,
) -> None:
    """Print the effective configuration (defaults, then --config, then --set) as commented YAML."""
    from mrnc_eval.commands.config_dump import subtree_yaml

    sys.stdout.write(subtree_yaml(_config(config, set_), key))


@app.command()
def info(
    log_path: Annotated[
        Path,
        typer.Argument(metavar="LOG", help="ROS 1 .bag, ROS 2 bag directory, .db3 or .mcap file."),
    ],
    json_out: JsonOpt = False,
    config: ConfigOpt = None,
    set_: SetOpt = None,
) -> None:
    """Summarise a log: container, duration, topics with type, count, rate and gaps, detected
    roles (--set io.roles.ROLE=TOPIC picks another topic for a role), and health findings (IMU
    rate and gaps, LiDAR fields, per-point time, IMU coverage
    of each sweep, GNSS fix ratio, duplicate or out-of-order stamps)."""
    cfg = _config(config, set_)
    from mrnc_eval.commands import info as info_command
    summary = info_command.run(log_path, cfg)
    if json_out:
        from mrnc_eval.commands.output import emit_json

        emit_json("info", [summary.json_item()], warnings=[f"{f.topic}: {f.message}" if f.topic else f.message
                                                           for f in summary.findings if f.level != "ok"])
    else:
        info_command.print_summary(summary)


class SlamMethod(StrEnum):  # a str: passed on as is
    lio = "lio"
    kiss_icp = "kiss-icp"


@app.command()
def slam(
    logs: Annotated[
        list[Path] | None,
        typer.Argument(metavar="LOG...", help="One or more logs (or folders of .bin/.pcd scans with "
                       "timestamps.txt, for --method kiss-icp); several give the Table I layout. "
                       "Not needed with --dump-config.", show_default=False),
    ] = None,
    method: Annotated[
        SlamMethod | None,
        typer.Option(help="SLAM method: lio (LIO-SAM replay) or kiss-icp (peer, needs the kiss-icp extra); "
                     "sets slam.method (default lio)."),
    ] = None,
    out: Annotated[Path, typer.Option(help="Output root; results go to OUT/<run>/.")] = Path("results"),
    no_loop: Annotated[bool, typer.Option("--no-loop", help="No loop closure (sets slam.loop.enabled=false).")] = False,
    no_gps: Annotated[bool, typer.Option("--no-gps", help="No GNSS factors (sets slam.gps.enabled=false).")] = False,
    topic: Annotated[str | None, typer.Option(
        "--topic", "-t", help="The LiDAR topic (kiss-icp's --topic; sets io.roles.lidar).")] = None,
    start: Annotated[float | None, typer.Option(
        "--start", help="Only sweeps from this many seconds after the log's start.")] = None,
    end: Annotated[float | None, typer.Option("--end", help="... up to this many seconds after it.")] = None,
    n_scans: Annotated[int | None, typer.Option(
        "--n-scans", "-n", help="At most this many sweeps (kiss-icp's --n-scans; lio: after its mapping-interval "
        "thinning).")] = None,
    threads: Annotated[int | None, typer.Option(
        "--threads", min=0, help="lio: threads (sets slam.threads; 0 = every core, 1 = one thread in turn, the "
        "serial run the default's poses equal to the bit).")] = None,
    json_out: JsonOpt = False,
    config: ConfigOpt = None,
    set_: SetOpt = None,
    dump_config: DumpOpt = False,
) -> None:
    """Re-run LIO-SAM-style LiDAR-inertial SLAM on recorded logs; write trajectories (TUM), the
    map, per-stage timing (ms/sweep), real-time factor, events and APE (m) against ground truth.
    Ground truth: a pose topic (Odometry, PoseStamped, ...) named like ground_truth or gt, or the one
    --set io.roles.ground_truth=TOPIC names (io.roles.ROLE=TOPIC picks the topic of any role), else
    <log>.gt.tum beside the log (TUM)."""
    from mrnc_eval import gc_pause

    gc_pause.pause()  # until the SLAM loop starts (gc_pause.py); whatever happens, on again after the command
    try:
        _slam(logs, method=method, out=out, flags=(no_loop, no_gps, json_out, dump_config), topic=topic,
              span=(start, end, n_scans), threads=threads, config=config, set_=set_)
    finally:
        gc_pause.end_command()


def _slam(logs: list[Path] | None, *, method: SlamMethod | None, out: Path, flags: tuple[bool, bool, bool, bool],
          topic: str | None, span: tuple[float | None, float | None, int | None], threads: int | None,
          config: Path | None, set_: list[str] | None) -> None:
    """`slam`'s body (flags: --no-loop, --no-gps, --json, --dump-config; span: --start, --end, --n-scans)."""
    no_loop, no_gps, json_out, dump_config = flags
    start, end, n_scans = span
    set_ = _slam_start(logs, method, threads, set_)
    cfg = _config(config, set_, dump_config)  # --dump-config needs no LOG
    if not logs:
        raise UsageError("slam needs LOG... (one or more logs; a folder of logs: mrnc-eval nightly FOLDER --out ROOT)")
    from mrnc_eval.extras import require_extra

    require_extra("slam", "mrnc-eval slam")
    if (_plain(method) or cfg.slam.method) == "kiss-icp":
        require_extra("kiss-icp", "mrnc-eval slam --method kiss-icp")
    from mrnc_eval.commands import slam as slam_command
    window = slam_command.SweepWindow(start_s=start, end_s=end, n_scans=n_scans)
    slam_command.main(logs, cfg, method=_plain(method), out=out, no_loop=no_loop, no_gps=no_gps, json_out=json_out,
                      topic=topic, window=window)


def _slam_start(logs: list[Path] | None, method: SlamMethod | None, threads: int | None,
                set_: list[str] | None) -> list[str] | None:
    """The --set overrides with --threads as slam.threads=N (so --dump-config shows it). First, for a
    lio run, gtsam's libraries are handed to the kernel to read ahead (extras.read_ahead): from a
    cold cache they come from disk while the config and the log's overview are read."""
    from mrnc_eval.extras import read_ahead

    if logs and _plain(method) != "kiss-icp":
        read_ahead("slam")
    return set_ if threads is None else [*(set_ or []), f"slam.threads={threads}"]


class ControlMode(StrEnum):
    replay = "replay"
    simulate = "simulate"
    sweep = "sweep"
    identify = "identify"
    tune = "tune"


@app.command()
def control(
    log_path: Annotated[
        Path | None,
        typer.Argument(metavar="LOG", help="Log to replay (optional with --mode simulate: the paper's scenario)."),
    ] = None,
    mode: Annotated[
        ControlMode,
        typer.Option(help="replay: evaluate recorded tracking; simulate: closed loop with the plant; "
                          "sweep: every controller on --runs drawn plants (robustness); identify: the drive "
                          "(gain, dead band, lag, delay per side) fitted to the LOG's commands and wheel speeds; "
                          "tune: every law tuned with the same optimiser, cost and budget, Table II at paper "
                          "and tuned gains."),
    ] = ControlMode.replay,
    controllers: Annotated[
        str | None,
        typer.Option(help="simulate, sweep: comma-separated raid,pid,apc,foptc,ff (apc and foptc are labelled "
                          "stand-ins; ff is the feed-forward alone, the negative control). Default: all.",
                     show_default=False),
    ] = None,
    runs: Annotated[int | None, typer.Option(help="sweep: plants drawn (default control.sweep.runs).")] = None,
    seed: Annotated[int | None, typer.Option(help="sweep: seed of the draws (default control.sweep.seed).")] = None,
    path: Annotated[Path | None, typer.Option(
        "--path", metavar="FILE", help="replay: the planned path as TUM poses (.tum, .txt) or CSV waypoints (.csv: "
        "x,y per line), in the frame of the recorded pose; replaces the log's path topic. Without a path the replay "
        "is wheel-speed tracking against the inverse kinematics of cmd_vel (or the wheel odometry's twist).")] = None,
    out: Annotated[Path, typer.Option(help="Output root; results go to OUT/<run>/.")] = Path("results"),
    json_out: JsonOpt = False,
    config: ConfigOpt = None,
    set_: SetOpt = None,
    dump_config: DumpOpt = False,
) -> None:
    """Re-run the control chain (pure pursuit -> inverse kinematics -> per-side controller ->
    hydraulic drive) and compute Table II metrics (settling time s, overshoot %, steady-state
    error m/s, funnel violations, saturation, safety stops, cross-track error m)."""
    cfg = _config(config, set_, dump_config)
    from mrnc_eval.extras import require_extra

    require_extra("control", "mrnc-eval control")
    from mrnc_eval.commands import control as control_command
    control_command.main(log_path, cfg, mode=mode.value, controllers=controllers, out=out, json_out=json_out,
                         runs=runs, seed=seed, path_file=path)


AlignOpt = Annotated[AlignMode, typer.Option(
    "--align", help="Alignment of each estimate to the reference. evo's switches work too: -a (se3), -as (sim3), "
    "-s (scale), --align_origin (origin).")]
NAlignOpt = Annotated[
    int | None, typer.Option("--n-to-align", "--n_to_align",
                             help="Align on the first N matched poses only (default: all).")
]


class RelationWord(StrEnum):
    """--relation's words: ours, then evo's (-r trans_part ...), which mean the same."""

    trans = "trans"
    rot = "rot"
    full = "full"
    angle_deg = "angle_deg"
    angle_rad = "angle_rad"
    point = "point"
    trans_part = "trans_part"
    rot_part = "rot_part"
    point_distance = "point_distance"


_EVO_RELATION = {"trans_part": Relation.trans, "rot_part": Relation.rot, "point_distance": Relation.point}


def _relation(word: RelationWord) -> Relation:
    return _EVO_RELATION.get(word.value) or Relation(word.value)


RelationOpt = Annotated[RelationWord, typer.Option(
    "--relation", "-r", "--pose_relation",
    help="Pose relation: trans (m), rot (unitless), full, angle_deg, angle_rad, point (m); evo's trans_part, "
    "rot_part, point_distance alike.")]
MaxDiffOpt = Annotated[float, typer.Option("--max-diff", "--t_max_diff",
                                           help="Association: maximum stamp difference, s.")]
OffsetOpt = Annotated[str, typer.Option(
    "--offset", "--t_offset",
    help="Added to the estimate's stamps, s; 'auto' estimates it (speed correlation, then least aligned APE).")]
StrictOpt = Annotated[bool, typer.Option(
    "--strict", help="Refuse repeated or out-of-order stamps (default: pair them as evo does, with a warning).")]


class SyncWord(StrEnum):
    nearest = "nearest"
    interpolate = "interpolate"
    nearest_time = "nearest_time"  # evo's words
    interpolation = "interpolation"


def _sync(word: SyncWord) -> SyncMethod:
    return {"nearest_time": SyncMethod.nearest, "interpolation": SyncMethod.interpolate}.get(
        word.value) or SyncMethod(word.value)


SyncOpt = Annotated[SyncWord, typer.Option(
    "--sync", "--sync_method",
    help="nearest: closest stamp within --max-diff (evo's nearest_time); interpolate: the reference at each "
    "estimate stamp (evo's interpolation).")]
MaxGapOpt = Annotated[float, typer.Option(
    "--max-gap", help="--sync interpolate: longest reference gap interpolated across, s.")]


class Plane(StrEnum):
    xy = "xy"
    xz = "xz"
    yz = "yz"


class PlotMode(StrEnum):  # evo's --plot_mode: which two axes the path plot shows
    xy = "xy"
    xz = "xz"
    yx = "yx"
    yz = "yz"
    zx = "zx"
    zy = "zy"
    xyz = "xyz"


PlaneOpt = Annotated[Plane | None, typer.Option("--plane", "--project_to_plane",
                                                help="Project to a plane before the metric.")]
TableOpt = Annotated[Path | None, typer.Option(help="Write the results table (.md, .tex, .csv or .html by suffix).")]
PlotOpt = Annotated[Path | None, typer.Option(
    "--plot", "--save_plot", help="Write a plot of the error (.svg, .png or .pdf).")]
LabelOpt = Annotated[list[str] | None, typer.Option(
    "--label", metavar="NAME", help="Name of an estimate in the table, plot and JSON; repeat once per EST, in "
    "order (default: a slam result's folder name, else the file name).")]
ApePlotOpt = Annotated[Path | None, typer.Option(
    "--plot", "--save_plot",
    help="Write the aligned path coloured by its error, the reference beside it (.svg, .png or .pdf).")]
PlotModeOpt = Annotated[PlotMode | None, typer.Option(
    "--plot-mode", "--plot_mode", help="Axes of the path plot (evo's --plot_mode; default xy).")]
SaveResultsOpt = Annotated[Path | None, typer.Option(
    "--save-results", "--save_results", metavar="RESULT.zip",
    help="Also write evo's result zip (evo_res, evo's API and mrnc-eval compare read it); one estimate.")]
FormatWordNote = ("REF may be preceded by evo's format word (tum, kitti, euroc, bag, bag2, mcap), which is ignored; "
                  "after bag/bag2/mcap: LOG REF_TOPIC EST_TOPIC...")


@app.command()
def ape(
    ref: Annotated[str, typer.Argument(metavar="REF", help="Reference: TUM, KITTI, EuRoC CSV or log.bag:/topic. "
                                       + FormatWordNote)],
    est: Annotated[list[str], typer.Argument(metavar="EST...", help="Estimates, same formats.")],
    align: AlignOpt = AlignMode.none,
    n_to_align: NAlignOpt = None,
    relation: RelationOpt = RelationWord.trans,
    max_diff: MaxDiffOpt = 0.01,
    offset: OffsetOpt = "0",
    plane: PlaneOpt = None,
    json_out: JsonOpt = False,
    table: TableOpt = None,
    plot: ApePlotOpt = None,
    plot_mode: PlotModeOpt = None,
    save_results: SaveResultsOpt = None,
    strict: StrictOpt = False,
    sync: SyncOpt = SyncWord.nearest,
    max_gap: MaxGapOpt = 0.2,
    decompose: Annotated[bool, typer.Option(
        "--decompose", help="Also along-track, cross-track, vertical (m) and yaw (deg) error statistics.")] = False,
    force: ForceOpt = False,
    label: LabelOpt = None,
) -> None:
    """Absolute pose error of each estimate against the reference (evo-compatible numbers; evo's
    command lines work: like evo, nothing is aligned unless asked, and the first line says which
    alignment was used)."""
    from mrnc_eval.commands import trajectory_eval as trajectory_eval_command
    trajectory_eval_command.ape_main(
        ref, est, align=align, n_to_align=n_to_align, relation=_relation(relation), max_diff=max_diff,
        offset=offset, plane=_plain(plane), json_out=json_out, table=table, plot=plot, strict=strict,
        sync=_sync(sync), max_gap=max_gap, decompose=decompose, plot_mode=_plain(plot_mode),
        save_results=save_results, force=force, labels=label,
    )


class DeltaWord(StrEnum):
    frames = "frames"
    m = "m"
    f = "f"  # evo's -u f


@app.command()
def rpe(
    ref: Annotated[str, typer.Argument(metavar="REF", help="Reference: TUM, KITTI, EuRoC CSV or log.bag:/topic. "
                                       + FormatWordNote)],
    est: Annotated[list[str], typer.Argument(metavar="EST...", help="Estimates, same formats.")],
    delta: Annotated[float | None, typer.Option("--delta", "-d", help="Pair spacing, in --delta-unit "
                                                "(default 1).")] = None,
    delta_unit: Annotated[DeltaWord, typer.Option(
        "--delta-unit", "-u", "--delta_unit", help="frames (evo's f) or m (distance travelled).")] = DeltaWord.frames,
    all_pairs: Annotated[bool, typer.Option("--all-pairs", "--all_pairs",
                                            help="Use all pairs instead of consecutive ones.")] = False,
    align: AlignOpt = AlignMode.none,
    n_to_align: NAlignOpt = None,
    relation: RelationOpt = RelationWord.trans,
    max_diff: MaxDiffOpt = 0.01,
    offset: OffsetOpt = "0",
    plane: PlaneOpt = None,
    json_out: JsonOpt = False,
    table: TableOpt = None,
    plot: PlotOpt = None,
    plot_mode: PlotModeOpt = None,
    save_results: SaveResultsOpt = None,
    strict: StrictOpt = False,
    sync: SyncOpt = SyncWord.nearest,
    max_gap: MaxGapOpt = 0.2,
    pairs_from_reference: Annotated[bool, typer.Option(
        "--pairs-from-reference", "--pairs_from_reference",
        help="Choose pairs on the reference path (default: on the estimate, as evo); "
        "a noisy estimate travels farther than the reference, so metre pairs from it are denser.")] = False,
    drift: Annotated[bool, typer.Option(
        "--drift", help="Also KITTI drift (translation % and deg/m over 100..800 m segments, "
        "scaled to short logs).")] = False,
    force: ForceOpt = False,
    label: LabelOpt = None,
) -> None:
    """Relative pose error over pairs spaced by --delta frames or metres (evo-compatible numbers;
    evo's command lines work)."""
    from mrnc_eval.commands import trajectory_eval as trajectory_eval_command
    trajectory_eval_command.rpe_main(
        ref, est, delta=delta, delta_unit=DeltaUnit.frames if delta_unit.value == "f" else DeltaUnit(delta_unit.value),
        all_pairs=all_pairs, align=align,
        n_to_align=n_to_align, relation=_relation(relation), max_diff=max_diff, offset=offset, plane=_plain(plane),
        json_out=json_out, table=table, plot=plot,
        pairs_from=PairsFrom.reference if pairs_from_reference else PairsFrom.estimate, drift=drift,
        strict=strict, sync=_sync(sync), max_gap=max_gap, plot_mode=_plain(plot_mode), save_results=save_results,
        force=force, labels=label,
    )


@app.command()
def table(
    source: Annotated[
        Path | None,
        typer.Argument(metavar="SOURCE", help="A folder of slam results (results/: one row per log, one column "
                       "per method, the newest run of each), a folder of sequence folders <seq>/<method>.tum "
                       "with <seq>/ground_truth.tum, or a YAML manifest. Not needed with --dump-config.",
                       show_default=False),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(help="Write the table (.md, .tex, .csv, .html by suffix); default: Markdown on stdout."),
    ] = None,
    align: AlignOpt = AlignMode.se3,
    max_diff: Annotated[float | None, typer.Option(
        "--max-diff", help="Association: maximum stamp difference, s (sets evaluation.max_diff_s).")] = None,
    json_out: JsonOpt = False,
    min_span_fraction: Annotated[float | None, typer.Option(
        help="A method whose matched span is shorter than this fraction of the reference's is Failed "
             "(sets evaluation.failed_min_span_fraction).")] = None,
    min_matches: Annotated[int | None, typer.Option(
        help="Fewer matched poses than this is Failed (sets evaluation.failed_min_matches).")] = None,
    force: ForceOpt = False,
    config: ConfigOpt = None,
    set_: SetOpt = None,
    dump_config: DumpOpt = False,
) -> None:
    """Table I layout: APE RMSE (m), sequences as rows, methods as columns, 'Failed' cells, mean row
    over non-failed cells, best per row marked. From slam result folders: each run's trajectory named
    by slam.table_trajectory (online or smoothed) against the ground truth the run found (its topic or
    <log>.gt.tum, recorded in result.json). A manifest (format below) names each sequence's reference
    and each method's estimate as ape reads them: files, result folders or log.bag:/topic."""
    shorthands = {"evaluation.max_diff_s": max_diff, "evaluation.failed_min_span_fraction": min_span_fraction,
                  "evaluation.failed_min_matches": min_matches}  # the flags are config keys: checked alike
    cfg = _config(config, [*(set_ or []), *(f"{k}={v}" for k, v in shorthands.items() if v is not None)],
                  dump_config)
    if source is None:
        raise UsageError("table needs SOURCE (a folder of slam results, of sequence folders, or a manifest)")
    from mrnc_eval.commands import table as table_command
    table_command.main(source, cfg, out=out, align=align, json_out=json_out, force=force)


@app.command()
def report(
    result_dirs: Annotated[
        list[Path],
        typer.Argument(metavar="RESULT_DIR...", help="Result directories written by info/slam/control, "
                       "or a folder holding them (a nightly per-log folder)."),
    ],
    out: Annotated[Path | None, typer.Option(help="Output directory (default: next to each result).")] = None,
    pdf: Annotated[bool, typer.Option("--pdf", help="Also write a PDF (WeasyPrint).")] = False,
    junit: JunitOpt = None,
    force: ForceOpt = False,
    appendix_config: Annotated[bool, typer.Option(
        "--appendix-config", help="Add the full effective configuration as an appendix (the report lists the keys "
        "that differ from the defaults; the full file is config.yaml beside each result).")] = False,
) -> None:
    """Render HTML (and PDF, CSV/LaTeX tables) reports of one log from its result directories; never recomputes."""
    from mrnc_eval.commands import report as report_command
    report_command.main(result_dirs, out=out, pdf=pdf, junit=junit, force=force, appendix_config=appendix_config)


@app.command()
def nightly(
    log_dir: Annotated[Path | None, typer.Argument(metavar="LOG_DIR", help="Folder searched recursively for logs "
                                                   "(not needed with --dump-config).", show_default=False)] = None,
    out: Annotated[Path | None, typer.Option(help="Report root: REPORT_ROOT/<date>/index.html, trends, history "
                                                  "(required).", show_default=False)] = None,
    jobs: Annotated[int, typer.Option(help="Parallel logs: 1 runs in-process, >1 a local process pool.")] = 2,
    scheduler: Annotated[str | None, typer.Option(help="Dask scheduler address tcp://HOST:PORT (dask extra).")] = None,
    since: Annotated[str | None, typer.Option(help="Only logs modified on or after this date (YYYY-MM-DD).")] = None,
    gates: Annotated[Path | None, typer.Option(help="YAML with gate thresholds (overrides config gates).")] = None,
    date: Annotated[str | None, typer.Option(help="Night label YYYY-MM-DD (default: today).")] = None,
    pdf: Annotated[bool, typer.Option("--pdf/--no-pdf", help="Also write PDF reports.")] = True,
    junit: JunitOpt = None,
    force: Annotated[bool, typer.Option("--force", help="Re-run every log, also those already processed with "
                                        "this configuration (unchanged logs are skipped otherwise).")] = False,
    config: ConfigOpt = None,
    set_: SetOpt = None,
    dump_config: DumpOpt = False,
) -> None:
    """Run slam + control + evaluation on every new log, write per-log reports, a night index and
    trends. Exit 3 if a log failed, 1 if a gate regressed, 0 otherwise. Ground truth: a pose topic
    named like ground_truth or gt, or the one --set io.roles.ground_truth=TOPIC names, else
    <log>.gt.tum beside the log (TUM)."""
    cfg = _config(config, set_, dump_config)  # --dump-config needs no LOG_DIR
    if log_dir is None or out is None:
        raise UsageError("nightly needs LOG_DIR and --out REPORT_ROOT (e.g. mrnc-eval nightly sample_logs "
                         "--out nightly_reports)")
    from mrnc_eval.extras import require_extra

    require_extra("slam", "mrnc-eval nightly (slam and control on every log)")
    require_extra("control", "mrnc-eval nightly (slam and control on every log)")
    if pdf:
        from mrnc_eval.reports.render import pdf_engine

        pdf_engine()  # before the night starts: --no-pdf, or the pdf extra
    from mrnc_eval.commands import nightly as nightly_command
    nightly_command.main(log_dir, cfg, out=out, jobs=jobs, scheduler=scheduler, since=since,
                              gates=gates, date=date, pdf=pdf, junit=junit, force=force)


@app.command()
def export(
    run_dirs: Annotated[
        list[Path],
        typer.Argument(metavar="RUN_DIR...", help="Result directories of one log (slam, control, info), "
                       "or a folder holding them (a nightly per-log folder)."),
    ],
    mcap: Annotated[Path, typer.Option(help="Output .mcap file (Foxglove / Lichtblick, JSON + Foxglove schemas).")],
    with_log: Annotated[bool, typer.Option("--with-log", help="Also copy the original log's sensor topics, raw.")]
    = False,
    force: Annotated[bool, typer.Option("--force", help="Replace an existing output file, only an export this "
                                        "tool wrote (never the log or ground truth a run read).")] = False,
) -> None:
    """Write one MCAP on the original log's timeline: trajectories and ground truth as poses, the
    APE (m) over time, the map (downsampled), the keyframe graph with loop closures, control
    references, speeds (m/s), commands (RPM), funnel, saturation and safety stops, events as logs."""
    from mrnc_eval.commands import export as export_command
    export_command.main(run_dirs, mcap=mcap, with_log=with_log, force=force)


class CompareFormat(StrEnum):
    terminal = "terminal"
    markdown = "markdown"
    html = "html"


@app.command()
def compare(
    runs: Annotated[
        list[Path] | None,
        typer.Argument(metavar="[RUN_A RUN_B]", help="Two result directories, or two folders of one log's results."),
    ] = None,
    history: Annotated[Path | None, typer.Option(help="Nightly report root (history.sqlite): compare two nights.")]
    = None,
    nights: Annotated[tuple[str, str] | None, typer.Option(help="The two nights of --history: D1 D2 (YYYY-MM-DD).")]
    = None,
    log_id: Annotated[str | None, typer.Option("--log", help="With --history: only this log id.")] = None,
    fmt: Annotated[CompareFormat, typer.Option("--format", help="Output on stdout.")] = CompareFormat.terminal,
    out: Annotated[Path | None, typer.Option(help="Write the tables to a .md or .html file instead.")] = None,
    changed_only: Annotated[bool, typer.Option("--changed-only", help="Leave out metrics that did not change.")]
    = False,
    force: ForceOpt = False,
) -> None:
    """The same metrics of two runs (or two nights) side by side with B - A and the relative change,
    and the configuration keys that differ."""
    from mrnc_eval.commands import compare as compare_command
    compare_command.main(runs or [], history=history, nights=nights, log_id=log_id, fmt=fmt.value, out=out,
                         only_changed=changed_only, force=force)


# choices of `simulate` (a test checks they match sim.scene.SCENES, recording.recorder.PATHS and LIDAR_MODELS)
class Scene(StrEnum):
    yard = "yard"
    forest = "forest"
    corridor = "corridor"
    field = "field"
    open_field = "open_field"


class SimPath(StrEnum):
    circle = "circle"
    figure8 = "figure8"
    loop = "loop"
    line = "line"


class LidarModel(StrEnum):
    os0_128 = "os0-128"
    os0_64 = "os0-64"
    os0_32 = "os0-32"


class SimProfile(StrEnum):
    ideal = "ideal"
    field = "field"


class LogFormat(StrEnum):
    mcap = "mcap"
    db3 = "db3"
    bag = "bag"


@app.command()
def simulate(
    out: Annotated[str | None, typer.Argument(
        metavar="OUT", help="Output log: NAME.bag (ROS 1 bag), NAME.mcap (ROS 2 MCAP), NAME.db3 (ROS 2 sqlite3), "
        "NAME/ (a ROS 2 bag folder); without a suffix, --format's is added. Not needed with --dump-config.")] = None,
    scene: Annotated[Scene, typer.Option(help="Scene.")] = Scene.yard,
    path: Annotated[SimPath, typer.Option(help="Path: circle is the paper's mission.")] = SimPath.circle,
    duration: Annotated[float | None, typer.Option(help="Duration, s (default: until the path is done).")] = None,
    lidar: Annotated[LidarModel, typer.Option(help="LiDAR model.")] = LidarModel.os0_128,
    columns: Annotated[int, typer.Option(help="Columns per sweep: 512, 1024 or 2048.")] = 1024,
    rate: Annotated[float, typer.Option(help="Sweep rate, Hz (10 or 20).")] = 10.0,
    fmt: Annotated[
        LogFormat | None,
        typer.Option("--format", help="mcap (ROS 2, zstd), db3 (ROS 2 sqlite3) or bag (ROS 1); default: from "
                     "OUT's suffix, mcap when it has none (must agree with the suffix)."),
    ] = None,
    seed: Annotated[int | None, typer.Option(help="Random seed (default: sim.seed, 0); the same seed gives "
                                                  "byte-identical logs.")] = None,
    profile: Annotated[SimProfile | None, typer.Option(help="Sensor profile: ideal (exact sensors, one clock) or field "
                                                     "(biases, vibration, clock offsets, miscalibrated tf, noisy "
                                                     "returns, body in the cloud, stones, a moving object, GNSS "
                                                     "multipath; sim.field.*). Default: sim.profile.")] = None,
    force: Annotated[bool, typer.Option("--force", help="Replace an existing log at OUT, only if this tool "
                                        "wrote it (a <name>.gt.tum is beside it).")] = False,
    config: ConfigOpt = None,
    set_: SetOpt = None,
    dump_config: DumpOpt = False,
) -> None:
    """Generate a synthetic skid-steer wheeled mobile robot (SSWMR) recording with exact ground
    truth (LiDAR, IMU, GNSS, wheel odometry, commands, path) driven in closed loop through the control chain."""
    cfg = _config(config, set_, dump_config)  # --dump-config needs no OUT
    if out is None:
        raise UsageError("simulate needs OUT, the log to write (e.g. sim/yard.mcap); see mrnc-eval simulate --help")
    from mrnc_eval.extras import require_extra

    require_extra("sim", "mrnc-eval simulate")
    from mrnc_eval.commands import simulate as simulate_command
    simulate_command.main(out, cfg, scene=scene.value, path=path.value, duration=duration, lidar=lidar.value,
                          columns=columns, rate=rate, fmt=_plain(fmt), seed=seed, profile=_plain(profile), force=force)


# ------------------------------------------------------------------ entry point


INTERNAL_ERROR = 5  # a bug, not a verdict on the input: never 1 ("a gate failed")
INTERRUPTED = 130  # Ctrl-C: 128 + SIGINT, as shells report it
BROKEN_PIPE = 0  # the reader stopped early (`info LOG | head -1`): it took what it wanted


def _on_sigint(signum: int, frame: Any) -> None:
    interrupt()


def _stdout_gone() -> int:
    """stdout's reader closed the pipe: say nothing more to it (the interpreter's last flush
    would fail again) and exit with BROKEN_PIPE."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    return BROKEN_PIPE


def _dispatch(argv: list[str] | None) -> Any:
    fast = fast_command(sys.argv[1:] if argv is None else argv, {"ape": ape, "rpe": rpe, "slam": slam})
    if fast is None or fast[0] is not slam:  # __main__ paused collection for a plain `slam` line only
        from mrnc_eval import gc_pause

        gc_pause.resume()
    if fast is None:
        return app(args=argv, prog_name="mrnc-eval", standalone_mode=False)
    _main()  # a plain ape/rpe/slam line: typer's per-run validators and pydantic ~0.1 s CPU (cli_fast)
    return fast[0](**fast[1])


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; the single place where errors become exit codes. Every error is one line on
    stderr (--debug adds the traceback): typed errors with their code, file-system errors
    (exists, permission, no space) with 4, anything else as an internal error with 5; Ctrl-C
    "interrupted" with 130; a closed stdout pipe (`| head`) 0."""
    import signal
    import threading

    previous = None
    forget_interrupt()
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGINT, _on_sigint)
    try:
        code = _run(argv)
        raise_if_interrupted()  # a Ctrl-C swallowed on the way (see errors.raise_if_interrupted) is still one
        return code
    except (Interrupted, KeyboardInterrupt):  # KeyboardInterrupt: where the handler is not installed
        sys.stderr.write("mrnc-eval: interrupted\n")
        return INTERRUPTED
    except BrokenPipeError:
        return _stdout_gone()
    except SystemExit as exc:  # click, typer and rich exit 1 on a broken pipe, raised while handling it
        cause = exc.__context__
        if isinstance(cause, OSError) and cause.errno == errno.EPIPE:
            return _stdout_gone()
        raise
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def _run(argv: list[str] | None) -> int:
    try:
        from mrnc_eval.cli_evo import translate

        result = _dispatch(translate(sys.argv[1:] if argv is None else list(argv)))  # evo's spellings first
    except typer.Exit as exc:
        return exc.exit_code
    except typer.Abort:
        sys.stderr.write("mrnc-eval: aborted\n")
        return INTERRUPTED
    except TyperException as exc:  # usage errors: missing argument, bad option value
        show = getattr(exc, "show", None)
        if callable(show):
            show()
        else:
            sys.stderr.write(f"mrnc-eval: usage error: {exc}\n")
        return 2
    except MrncError as exc:
        if _state["debug"]:
            log.exception("%s", exc)
        sys.stderr.write(f"mrnc-eval: error: {printable(str(exc))}\n")
        return exc.exit_code
    except BrokenPipeError:
        raise  # main() turns it into BROKEN_PIPE
    except OSError as exc:  # a file-system error no layer below turned into a typed one
        from mrnc_eval.results import describe_os_error

        if _state["debug"]:
            log.exception("%s", exc)
        sys.stderr.write(f"mrnc-eval: error: {printable(describe_os_error(exc))}\n")
        return 4
    except Exception as exc:
        if _state["debug"]:
            log.exception("%s", exc)
        sys.stderr.write(f"mrnc-eval: internal error: {type(exc).__name__}: {printable(str(exc))[:300]} "
                         "(a bug; --debug shows the traceback)\n")
        return INTERNAL_ERROR
    return result if isinstance(result, int) else 0


if __name__ == "__main__":
    sys.exit(main())
