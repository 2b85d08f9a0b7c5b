"""A planned path supplied after the fact (`control --path FILE`): TUM poses (`stamp x y z qx qy
qz qw`, the trajectory parser everything else uses) or CSV waypoints (`x,y` or `x,y,z` per line;
a header row naming the columns `x` and `y` may put them anywhere). Errors name the file and line."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from mrnc_eval.data import Waypoints
from mrnc_eval.errors import InputError
from mrnc_eval.io.trajectory_files import read_tum

WAYPOINT_SUFFIXES = (".tum", ".txt", ".csv")


def read_waypoints(path: str | Path) -> Waypoints:
    """The (N, 2) waypoints (m, in the frame of the recorded pose) of a TUM or CSV file."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "no such file" if not path.exists() else "not a file")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        xy = _read_csv(path)
    elif suffix in (".tum", ".txt"):
        xy = read_tum(path).positions[:, :2]
    else:
        raise InputError(path, f"unknown waypoint file {suffix or '(no suffix)'}: .tum or .txt (TUM: stamp x y z qx "
                               "qy qz qw per line) or .csv (x,y per line)")
    if xy.shape[0] < 2:
        raise InputError(path, f"a path needs at least 2 waypoints, the file holds {xy.shape[0]}")
    return Waypoints(np.ascontiguousarray(xy, dtype=np.float64))


def _read_csv(path: Path) -> np.ndarray:
    rows: list[tuple[float, float]] = []
    columns: tuple[int, int] | None = None  # (x, y) column of a header row
    with path.open(encoding="utf-8-sig", errors="replace") as fh:
        for number, line in enumerate(fh, 1):
            text = line.strip()
            if not text or text.startswith("#"):
                continue
            fields = [f.strip() for f in text.split(",")]
            if not rows and columns is None and not _is_number(fields[0]):
                names = [f.lower() for f in fields]
                if "x" not in names or "y" not in names:
                    raise InputError(path, f"line {number}: a header row must name the columns x and y, "
                                           f"got {text[:60]!r}")
                columns = names.index("x"), names.index("y")
                continue
            ix, iy = columns or (0, 1)
            if columns is None and len(fields) not in (2, 3):
                raise InputError(path, f"line {number} has {len(fields)} fields, expected x,y or x,y,z")
            if max(ix, iy) >= len(fields):
                raise InputError(path, f"line {number} has {len(fields)} fields, the header names {max(ix, iy) + 1}")
            for value in (fields[ix], fields[iy]):
                if not _is_number(value) or not math.isfinite(float(value)):
                    raise InputError(path, f"line {number}: {value[:20]!r} is not a finite number")
            rows.append((float(fields[ix]), float(fields[iy])))
    if not rows:
        raise InputError(path, "no waypoints (the file is empty or only comments)")
    return np.asarray(rows, dtype=np.float64)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
