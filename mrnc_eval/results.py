"""Result objects: what every pipeline writes and what reports render (never recomputing).

A result directory `OUT/<run>/` holds:
  result.json   kind, provenance, metrics (value + unit), tables, events, warnings, extra
  series.npz    named numpy arrays for figures (loaded with allow_pickle=False)
  config.yaml   the effective configuration
plus whatever files the pipeline adds (TUM trajectories, the map). Directories are
written under a temporary name and renamed into place, so a reader never sees half a result.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import re
import shutil
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mrnc_eval import __version__
from mrnc_eval.errors import InputError
from mrnc_eval.tables import Table

if TYPE_CHECKING:
    import pandas as pd

RESULT_FILE = "result.json"
SERIES_FILE = "series.npz"
CONFIG_FILE = "config.yaml"


@dataclass
class Metric:
    name: str  # unit-bearing key, e.g. "ape_rmse_m", "settling_time_s"
    value: float | int | None
    unit: str = ""
    group: str = ""  # e.g. "slam", "control/raid/left"
    lower_is_better: bool = True
    note: str = ""


@dataclass
class Event:
    t_s: float  # seconds since the log start
    kind: str  # "loop_closure", "degeneracy", "safety_stop", "slip", ...
    message: str
    data: dict[str, Any] = field(default_factory=dict)


@dataclass
class RunResult:
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


def log_id_for(path: str | Path) -> str:
    """Stable id of a log: its sanitised name without the container suffix."""
    p = Path(path)
    stem = p.name
    for suffix in (".mcap", ".db3", ".bag"):
        if stem.endswith(suffix):
            stem = stem[: -len(suffix)]
            break
    return safe_name(stem)


def atomic_write_text(path: Path, text: str) -> None:
    """Write a file under a temporary name and rename it into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
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
    one is complete.
    """
    run_dir = Path(run_dir)
    run_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{run_dir.name}.", suffix=".partial", dir=run_dir.parent))
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
        if run_dir.exists():
            old = run_dir.with_name(f".{run_dir.name}.old")
            shutil.rmtree(old, ignore_errors=True)
            os.replace(run_dir, old)
            os.replace(tmp, run_dir)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, run_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return run_dir


def _restore_float(value: Any) -> Any:
    if value == "inf":
        return math.inf
    if value == "-inf":
        return -math.inf
    return value


def read_result(run_dir: str | Path) -> RunResult:
    """Load a result directory written by `write_result` (no pickle, ever)."""
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
    if npz.exists():
        with np.load(npz, allow_pickle=False) as data:
            series = {k: data[k] for k in data.files}
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
