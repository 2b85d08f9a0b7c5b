"""Result objects: what every pipeline writes and what reports render (never recomputing).

A result directory `OUT/<run>/` holds:
  result.json   kind, provenance, metrics (value + unit), tables, events, warnings, extra
  series.npz    named numpy arrays for figures (loaded with allow_pickle=False)
  config.yaml   the effective configuration
plus whatever files the pipeline adds (TUM trajectories, the map). Directories are
written under a temporary name and renamed into place, so a reader never sees half a result.

Outputs never destroy anything: every run gets a new folder (`new_run_dir`: log id, verb, UTC
second and a random suffix), an existing folder is replaced only when it holds a result this
tool wrote, output roots are checked before long work starts (`check_output_root`), and every
file and folder gets the permissions the umask gives (temporary files are created 0600/0700).
"""

from __future__ import annotations

import datetime as _dt
import errno
import hashlib
import json
import logging
import math
import os
import re
import secrets
import shutil
import tempfile
import unicodedata
import zipfile
import zlib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mrnc_eval import __version__
from mrnc_eval.errors import InputError, OutputError, raise_if_interrupted
from mrnc_eval.io.containers import LOG_SUFFIXES
from mrnc_eval.outputs import describe, follow_umask
from mrnc_eval.tables import Table

if TYPE_CHECKING:
    import pandas as pd

RESULT_FILE = "result.json"
SERIES_FILE = "series.npz"
CONFIG_FILE = "config.yaml"


# Which way is better, per metric name: True lower, False higher. A name not here has no known
# direction (counts such as matched poses, keyframes, loop closures; settings such as the
# mapping rate; signed biases): `compare` gives it no verdict.
_LOWER = ("ape_rmse_m", "ape_online_rmse_m", "ape_gnss_rmse_m", "ape_max_m", "ape_mean_m", "end_drift_m",
          "end_drift_online_m", "degeneracy_events", "map_entropy", "map_plane_variance_m2", "completion_time_s",
          "control_effort", "cross_track_max_m", "cross_track_mean_abs_m", "cross_track_p95_m", "cross_track_rms_m",
          "final_position_error_m", "funnel_violations", "heading_error_rms_rad", "iae", "ise", "itae",
          "longest_saturation_s", "max_abs_error_mps", "max_e_over_o", "overshoot_pct", "paper_overshoot_pct",
          "paper_settling_time_s", "paper_steady_state_error_mps", "recovery_time_s", "rise_time_s",
          "rms_error_mps", "safety_stops", "saturation_ratio", "settling_time_s", "steady_state_error_mps",
          "total_variation_rpm", "sweeps_empty", "sweeps_without_imu")
_HIGHER = ("rtf", "rtf_end_to_end")
METRIC_DIRECTION: dict[str, bool] = {**dict.fromkeys(_LOWER, True), **dict.fromkeys(_HIGHER, False)}


def metric_direction(name: str, stored: bool | None = None) -> bool | None:
    """True: lower is better, False: higher, None: unknown. The table above first (result files
    written before it stored True for every metric, counts included); then an explicit stored
    direction other than that old default (a metric added elsewhere with lower_is_better=False)."""
    if name.startswith("ms_per_sweep_"):
        return True
    if name in METRIC_DIRECTION:
        return METRIC_DIRECTION[name]
    return False if stored is False else None


@dataclass(kw_only=True)
class Metric:
    """One named value of a run, with its unit."""

    name: str  # unit-bearing key, e.g. "ape_rmse_m", "settling_time_s"
    value: float | int | None
    unit: str = ""
    group: str = ""  # e.g. "slam", "control/raid/left"
    lower_is_better: bool | None = None  # None: from METRIC_DIRECTION by name (None there: unknown)
    note: str = ""

    def __post_init__(self) -> None:
        if self.lower_is_better is None:
            self.lower_is_better = metric_direction(self.name)


@dataclass(kw_only=True)
class Event:
    """Something that happened during a run, at a log time."""

    t_s: float  # seconds since the log start
    kind: str  # "loop_closure", "degeneracy", "safety_stop", "slip", ...
    message: str
    data: dict[str, Any] = field(default_factory=dict)


@dataclass(kw_only=True)
class RunResult:
    """Everything one run produced: metrics, events, warnings, series and provenance."""

    kind: str  # "slam" | "control" | "info"
    log_path: str
    log_id: str
    metrics: list[Metric] = field(default_factory=list)
    tables: list[Table] = field(default_factory=list)
    events: list[Event] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)  # JSON-serialisable details (timing, info summary)
    series: dict[str, np.ndarray] = field(default_factory=dict)  # arrays for figures
    config_hash: str = ""
    tool_version: str = __version__
    created_utc: str = field(default_factory=lambda: _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"))

    def metric(self, name: str) -> Metric | None:
        return next((m for m in self.metrics if m.name == name), None)

    def to_dataframe(self) -> pd.DataFrame:
        """The metrics, one row each: kind, log_id, group, name, value, unit, lower_is_better, note."""
        import pandas as pd

        return pd.DataFrame([{"kind": self.kind, "log_id": self.log_id, **asdict(m)} for m in self.metrics],
                            columns=["kind", "log_id", "group", "name", "value", "unit", "lower_is_better", "note"])


# ------------------------------------------------------------------ names and atomic IO

_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


def safe_name(text: str, max_len: int = 80) -> str:
    """A file-name-safe version of text taken from a log (topic names, log stems).

    Path separators, `..` and control characters cannot survive, so a hostile log cannot
    make us write outside the output root.
    """
    name = _UNSAFE.sub("_", text).strip("._")
    name = re.sub(r"\.{2,}", "_", name)
    return (name or "unnamed")[:max_len]


def _strip_log_suffix(name: str) -> str:
    for suffix in LOG_SUFFIXES:
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return name


def stable_id(relative: str | Path) -> str:
    """A file-name-safe id that depends only on `relative` (a path relative to a search root):
    the path itself joined with "_" when it is plain ASCII ("nested/b.bag" -> "nested_b"),
    otherwise a readable ASCII slug plus a short hash of the relative path
    ("München/ß.mcap" -> "Munchen-" + 8 hex digits). Adding or removing other files never changes it."""
    parts = [str(p) for p in Path(relative).parts]
    if not parts:
        return "unnamed"
    parts[-1] = _strip_log_suffix(parts[-1])
    joined = "_".join(parts)
    slug = safe_name(unicodedata.normalize("NFKD", joined).encode("ascii", "ignore").decode("ascii"), max_len=60)
    if slug == joined and slug != "unnamed":
        return slug
    return f"{slug}-{path_hash(relative)}"


def path_hash(relative: str | Path) -> str:
    """8 hex digits of a relative path (its POSIX form, bytes as stored)."""
    return hashlib.sha256(Path(relative).as_posix().encode("utf-8", "surrogateescape")).hexdigest()[:8]


def absolute_log_path(path: str | Path) -> str:
    """The log path as result.json records it: absolute (each file of a split log "a.mcap,b.mcap"),
    so `export --with-log`, `report` and `table` find the log from any working folder."""
    from mrnc_eval.io.split_logs import split_log_paths

    parts = split_log_paths(path)
    if parts is not None:
        return ",".join(str(p.absolute()) for p in parts)
    return str(Path(path).absolute())


def log_id_for(path: str | Path) -> str:
    """Stable id of a log from its file name (see `stable_id`), without the container suffix."""
    return stable_id(Path(path).name)


def check_output_root(root: Path, need_bytes: int = 0) -> Path:
    """Before long work: `root` is (or can be made) a writable folder with `need_bytes` free.
    Raises OutputError naming the folder and the problem."""
    root = Path(root)
    if root.exists() and not root.is_dir():
        raise OutputError(root, "exists and is not a folder (choose another --out)")
    try:
        root.mkdir(parents=True, exist_ok=True)
        probe = tempfile.NamedTemporaryFile(prefix=".mrnc-write-probe.", dir=root)  # noqa: SIM115
        probe.close()
    except OSError as err:
        raise OutputError(root, f"cannot write here: {err.strerror or err}") from err
    free = shutil.disk_usage(root).free
    if free < need_bytes:
        raise OutputError(root, f"only {free / 1e6:.0f} MB free, about {need_bytes / 1e6:.0f} MB needed")
    return root


def new_run_dir(root: Path, log_id: str, verb: str) -> Path:
    """A fresh, unused result folder name under `root`: `<log id>-<verb>-<UTC second>-<random>`,
    so two runs never share a folder (same log name in two places, same second)."""
    stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    while True:
        candidate = Path(root) / safe_name(f"{log_id}-{verb}-{stamp}-{secrets.token_hex(3)}", max_len=120)
        if not candidate.exists():
            return candidate


def atomic_write_text(path: Path, text: str) -> None:
    """Write a file under a temporary name and rename it into place (mode from the umask)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as err:
        raise OutputError(path, f"cannot write here: {describe(err)}") from err
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        follow_umask(Path(tmp))
        os.replace(tmp, path)
    except OSError as err:  # the target named, not the temporary file
        Path(tmp).unlink(missing_ok=True)
        raise OutputError(path, f"cannot write: {describe(err)}") from err
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def json_safe(value: Any) -> Any:
    """Plain JSON values: numpy scalars and arrays as Python ones, NaN as null, inf as "inf"."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, Path):
        return str(value)
    return value


def write_result(result: RunResult, run_dir: Path, config_yaml: str, files: dict[str, Path] | None = None) -> Path:
    """Write `result` to `run_dir` atomically (temporary sibling directory, then rename).

    `files` maps names inside the run directory to already-written temporary files that
    are moved in (trajectories, maps). An existing `run_dir` is replaced only once the new
    one is complete, and only when it is empty or a result this tool wrote; anything else is
    an OutputError and left untouched.
    """
    run_dir = Path(run_dir)
    _check_replaceable(run_dir)
    try:
        run_dir.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{run_dir.name}.", suffix=".partial", dir=run_dir.parent))
    except OSError as err:
        raise OutputError(run_dir, f"cannot write here: {describe(err)}") from err
    follow_umask(tmp)
    try:
        body = asdict(result)
        body.pop("series")
        (tmp / RESULT_FILE).write_text(json.dumps(json_safe(body), indent=2), encoding="utf-8")
        arrays = {safe_name(k): np.asarray(v) for k, v in result.series.items()}
        for key, arr in arrays.items():
            if arr.dtype.hasobject:  # would need pickle to store and to load
                raise TypeError(f"series {key!r} has dtype object; store numbers or strings")
        # numpy's stub types **kwds like its allow_pickle flag; the arrays are plain numeric arrays
        np.savez_compressed(tmp / SERIES_FILE, **arrays)  # type: ignore[arg-type]
        (tmp / CONFIG_FILE).write_text(config_yaml, encoding="utf-8")
        for name, src in (files or {}).items():
            dest = tmp / safe_name(name, max_len=120)
            shutil.move(str(src), dest)
        raise_if_interrupted()  # never commit a run a Ctrl-C may have cut short
        if run_dir.exists():
            old = run_dir.with_name(f".{run_dir.name}.old")
            shutil.rmtree(old, ignore_errors=True)
            os.replace(run_dir, old)
            os.replace(tmp, run_dir)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, run_dir)
    except OSError as err:  # name the result folder, not the hidden temporary one (no space, permission)
        shutil.rmtree(tmp, ignore_errors=True)
        raise OutputError(run_dir, f"cannot write: {describe(err)}") from err
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return run_dir


def claim_run_dir(run_dir: str | Path, *, force: bool = False) -> Path:
    """The one overwrite rule (mrnc_eval/outputs.py) for a result folder named by the caller (the
    API's out_dir): a missing or empty folder is written; an existing result is refused unless
    `force`, and `force` replaces only a result this tool wrote."""
    run_dir = Path(run_dir)
    if run_dir.is_dir() and not run_dir.is_symlink() and not any(run_dir.iterdir()):
        return run_dir
    if run_dir.exists() or run_dir.is_symlink():
        if not force:
            raise OutputError(run_dir, "already exists; not replaced (force=True replaces a result this tool wrote)")
        _check_replaceable(run_dir)
    return run_dir


def _check_replaceable(run_dir: Path) -> None:
    if not run_dir.exists() and not run_dir.is_symlink():
        return
    if run_dir.is_symlink() or not run_dir.is_dir():
        raise OutputError(run_dir, "exists and is not a result folder; not replaced")
    if any(run_dir.iterdir()) and not (run_dir / RESULT_FILE).is_file():
        raise OutputError(run_dir, "folder exists and holds files this tool did not write; not replaced")


def describe_os_error(err: OSError) -> str:
    """One line for a file-system error: the file and the system's reason (no traceback)."""
    reason = err.strerror or type(err).__name__
    if err.errno == errno.ENOSPC:
        reason = "no space left on device"
    where = err.filename if err.filename is not None else ""
    return f"{where}: {reason}" if where else reason


def _restore_float(value: Any) -> Any:
    if value == "inf":
        return math.inf
    if value == "-inf":
        return -math.inf
    return value


def read_result(run_dir: str | Path, *, with_series: bool = True) -> RunResult:
    """Load a result directory written by `write_result` (no pickle, ever); without its arrays
    (series.npz) when only the metrics and details are needed."""
    run_dir = Path(run_dir)
    path = run_dir / RESULT_FILE
    try:
        body = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as err:
        raise InputError(run_dir, f"not a result directory (no {RESULT_FILE})") from err
    except (OSError, json.JSONDecodeError) as err:
        raise InputError(path, f"unreadable result: {err}") from err
    series: dict[str, np.ndarray] = {}
    npz = run_dir / SERIES_FILE
    if with_series and npz.exists():
        try:
            with np.load(npz, allow_pickle=False) as data:
                series = {k: data[k] for k in data.files}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as err:  # truncated, flipped, not a zip
            raise InputError(npz, f"damaged series file: {err}") from err
    try:
        return RunResult(
            kind=body["kind"],
            log_path=body["log_path"],
            log_id=body["log_id"],
            metrics=[Metric(**{**m, "value": _restore_float(m["value"])}) for m in body.get("metrics", [])],
            tables=[Table(**t) for t in body.get("tables", [])],
            events=[Event(**e) for e in body.get("events", [])],
            warnings=list(body.get("warnings", [])),
            extra=body.get("extra", {}),
            series=series,
            config_hash=body.get("config_hash", ""),
            tool_version=body.get("tool_version", ""),
            created_utc=body.get("created_utc", ""),
        )
    except (KeyError, TypeError) as err:
        raise InputError(path, f"invalid result: {err}") from err


LATEST_LINK = "latest"


def link_latest(target: Path) -> Path:
    """Point `target.parent/latest` at `target` (relative symlink, replaced atomically), so the
    newest run or night is always at OUT/latest."""
    link = target.parent / LATEST_LINK
    if link.exists() and not link.is_symlink():  # a file or folder of the user's: never replaced
        logging.getLogger(__name__).warning("%s exists and is not our link; not updated", link)
        return link
    tmp = target.parent / f".{LATEST_LINK}.{os.getpid()}.tmp"
    tmp.unlink(missing_ok=True)
    tmp.symlink_to(target.name, target_is_directory=True)
    os.replace(tmp, link)
    return link
