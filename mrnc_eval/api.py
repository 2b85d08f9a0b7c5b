"""Python API for notebooks and scripts: the functions the CLI verbs run, returning the same
result objects the CLI writes, each with `.to_dataframe()` (pandas).

    from mrnc_eval import api

    result = api.run_slam("sample_logs/loop_forest.bag", "results/loop")   # RunResult, as `mrnc-eval slam`
    result.to_dataframe()                                       # one row per metric
    ape = api.ape("sample_logs/loop_forest.gt.tum", "results/loop/trajectory.tum")
    ape.stats["rmse"], ape.to_dataframe()                       # one row per matched pose
    api.load_history("nightly_reports")                         # every night's metrics

Each function is a thin wrapper over the command or evaluation code the CLI calls: the same
numbers, files and errors (typed, from mrnc_eval.errors). Configuration: pass a `Config`
(`api.config("cfg.yaml", ["control.raid.beta=1.5"])`) or overrides as KEY=VALUE strings."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mrnc_eval.config import Config, load_config
from mrnc_eval.data import Trajectory
from mrnc_eval.evaluation.ape import ApeResult
from mrnc_eval.evaluation.rpe import RpeResult
from mrnc_eval.io import LogReader
from mrnc_eval.io.evo_results import EvoResult
from mrnc_eval.results import RunResult

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["ape", "config", "load_evo_result", "load_history", "load_result", "read_log", "read_trajectory", "rpe",
           "run_control", "run_slam", "save_evo_result"]

TrajectoryLike = Trajectory | str | Path  # a trajectory, a file (TUM, KITTI, EuRoC) or "log.mcap:/topic"


def config(path: str | Path | None = None, overrides: Sequence[str] = ()) -> Config:
    """The effective configuration: defaults, then a YAML file, then KEY=VALUE overrides."""
    return load_config(path, overrides)


def _cfg(cfg: Config | None, overrides: Sequence[str]) -> Config:
    if cfg is not None and overrides:
        from mrnc_eval.errors import UsageError

        raise UsageError("pass cfg or overrides, not both (api.config(path, overrides) builds a Config)")
    return cfg if cfg is not None else load_config(None, overrides)


def read_log(path: str | Path, cfg: Config | None = None) -> LogReader:
    """An open log (ROS 1 bag, ROS 2 bag directory, .db3, .mcap); use it in a `with` block."""
    from mrnc_eval.io import open_log

    return open_log(path, (cfg or Config()).io)


def read_trajectory(spec: TrajectoryLike) -> Trajectory:
    """A trajectory from a TUM/KITTI/EuRoC file or a `log.mcap:/topic` spec (as `mrnc-eval ape` reads)."""
    from mrnc_eval.io.trajectory_files import check_trajectory
    from mrnc_eval.io.trajectory_files import read_trajectory as read

    return check_trajectory(spec) if isinstance(spec, Trajectory) else read(spec)


def _checked_options(compute: Any, options: dict[str, Any], verb: str) -> dict[str, Any]:
    """The options of api.ape/rpe checked as the CLI checks its flags: unknown names, choices
    outside their enumeration and offsets that are not seconds are UsageError/EvaluationError
    with the CLI's words, never a TypeError or ValueError from deep inside."""
    import inspect

    from mrnc_eval.commands.trajectory_eval import parse_offset
    from mrnc_eval.errors import EvaluationError, UsageError
    from mrnc_eval.evaluation.modes import AlignMode, DeltaUnit, PairsFrom, Relation, SyncMethod

    known = [p for p in inspect.signature(compute).parameters if p not in ("ref", "est")]
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise UsageError(f"api.{verb}: unknown option(s) {', '.join(unknown)}; options: {', '.join(known)}")
    choices = {"align": AlignMode, "relation": Relation, "sync": SyncMethod, "delta_unit": DeltaUnit,
               "pairs_from": PairsFrom}
    for key, enum in choices.items():
        value = options.get(key)
        if value is not None and str(value) not in {e.value for e in enum}:
            raise EvaluationError(f"unknown {key} {value!r}; choose one of {', '.join(e.value for e in enum)}")
    if "offset" in options:
        offset = parse_offset(options["offset"])
        if offset is None:
            raise UsageError(f"api.{verb}: offset='auto' is the CLI's estimate; pass seconds (a number)")
        options = {**options, "offset": offset}
    return options


def ape(ref: TrajectoryLike, est: TrajectoryLike, **options: Any) -> ApeResult:
    """Absolute pose error (evo-compatible); options as `mrnc-eval ape`: align="none" (evo's default;
    "se3", "sim3", "scale", "origin", "yaw"), relation="trans", max_diff=0.01, offset=0.0,
    n_to_align=None, plane=None. Bad input raises the CLI's typed errors."""
    from mrnc_eval.evaluation.ape import ape as compute

    options = _checked_options(compute, {"align": "none", **options}, "ape")
    return compute(read_trajectory(ref), read_trajectory(est), **options)


def load_evo_result(path: str | Path) -> EvoResult:
    """An evo result zip (`evo_ape/evo_rpe --save_results`, or ours): info (title, names, label),
    stats and the arrays (error_array, timestamps, seconds_from_start, distances...). Arrays are read
    with allow_pickle=False: a zip is never unpickled."""
    from mrnc_eval.io.evo_results import read_evo_zip

    return read_evo_zip(path)


def save_evo_result(path: str | Path, result: ApeResult | RpeResult, *, ref_name: str = "reference",
                    est_name: str | None = None, force: bool = False) -> None:
    """`result` as evo's result zip (what `--save_results` writes; evo_res reads it), under the
    overwrite rule of every output (an existing file only with force=True, and only one we wrote)."""
    from mrnc_eval.io.evo_results import evo_result, evo_zip_bytes
    from mrnc_eval.outputs import write_output

    write_output(Path(path), evo_zip_bytes(evo_result(result, ref_name=ref_name, est_name=est_name or result.name)),
                 force=force)


def rpe(ref: TrajectoryLike, est: TrajectoryLike, **options: Any) -> RpeResult:
    """Relative pose error (evo-compatible); options as `mrnc-eval rpe`: delta=1.0, delta_unit="frames",
    all_pairs=False, relation="trans", align="none", pairs_from="estimate"... Bad input raises the
    CLI's typed errors."""
    from mrnc_eval.evaluation.rpe import rpe as compute

    options = _checked_options(compute, options, "rpe")
    return compute(read_trajectory(ref), read_trajectory(est), **options)


def run_slam(log: str | Path, out_dir: str | Path, *, method: str = "lio", cfg: Config | None = None,
             overrides: Sequence[str] = (), force: bool = False) -> RunResult:
    """The SLAM replay of `mrnc-eval slam` on one log; writes its result directory to `out_dir`
    (an existing result there is replaced only with force=True; anything else never)."""
    from mrnc_eval.commands.slam import run_log
    from mrnc_eval.results import claim_run_dir

    claim_run_dir(out_dir, force=force)  # before the work
    return run_log(Path(log), _cfg(cfg, overrides), Path(out_dir), method=method)


def run_control(log: str | Path | None, out_dir: str | Path, *, mode: str = "replay",
                controllers: Sequence[str] | None = None, cfg: Config | None = None,
                overrides: Sequence[str] = (), path: str | Path | None = None, force: bool = False) -> RunResult:
    """The control evaluation of `mrnc-eval control` (mode "replay" or "simulate"; log None with
    "simulate": the paper's circle); writes its result directory to `out_dir`. `path`: a TUM or
    CSV waypoint file replacing the log's path topic (`--path`)."""
    from mrnc_eval.commands.control import parse_controllers, run_log
    from mrnc_eval.control.controllers import CONTROLLERS
    from mrnc_eval.io.waypoint_files import read_waypoints
    from mrnc_eval.results import claim_run_dir

    claim_run_dir(out_dir, force=force)  # before the work
    waypoints = read_waypoints(path) if path is not None else None
    return run_log(None if log is None else Path(log), _cfg(cfg, overrides), Path(out_dir), mode=mode,
                   controllers=parse_controllers(controllers if isinstance(controllers, str) else ",".join(controllers))
                   if controllers else CONTROLLERS, path=waypoints,
                   path_source=f"{path} (--path)")


def load_result(run_dir: str | Path) -> RunResult:
    """A result directory written by the CLI (slam, control, info), as `mrnc-eval report` reads it."""
    from mrnc_eval.results import read_result

    return read_result(Path(run_dir))


def load_history(root: str | Path) -> pd.DataFrame:
    """The nightly history of a report root (ROOT/history.sqlite): one row per night, log and metric,
    columns night, log_id, metric, value, unit, status, config_hash."""
    import pandas as pd

    from mrnc_eval.history import METRIC_ROW_COLUMNS, open_history

    return pd.DataFrame(open_history(Path(root)).metric_rows(), columns=list(METRIC_ROW_COLUMNS))
