"""Whitespace tables of numbers (TUM, KITTI poses): a fast path for plain files, a strict one
that names the first bad line.

Fast path: a small C reader (`_numtext.c`, built at install by setup.py; without a compiler the
strict path reads everything) that writes the numbers straight into the (columns, rows) result,
without the GIL. It takes only plain files (rows of exactly `ncols` decimal numbers separated by
single spaces, empty and ASCII '#' lines) and hands anything else to the strict path, which
parses exactly as before: pandas' C parser, comments anywhere, and an error naming the file and
line. The C reader rounds as float() does; the tests hold both paths to the same bits or error.

Measured (issue 14), one 1e6-pose TUM file -> (8, n) float64 in a fresh process, CPU s and peak
MB of the whole process (python + numpy alone: 0.12 s, 25 MB): this C reader 0.31 s, 88 MB (one pass
over each line since issue 30: two 91 MB files 0.35 -> 0.24 s CPU);
pandas 0.69 s, 199 MB; pyarrow's CSV reader streamed into the result 0.45 s, 153 MB (the library
alone ~55 MB); np.loadtxt 1.55 s, 90 MB; numpy vectorised over a memory map 1.9 s, 512 MB; a numba
kernel (an earlier session) about pandas' parse time plus 0.3 s of import and 115 MB.
"""

from __future__ import annotations

import math
import mmap
import os
import stat
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.errors import InputError


def read_columns(path: Path, ncols: int) -> NDArray[np.float64]:
    """(ncols, rows) float64 of a file of rows of `ncols` numbers separated by single spaces;
    '#' comment lines and empty lines are skipped. InputError names the file and first bad line."""
    fast = _fast_columns(path, ncols)
    return fast if fast is not None else _strict_table(path, ncols).T


def _fast_columns(path: Path, ncols: int) -> NDArray[np.float64] | None:
    """The table when the file is plain and the C reader is built, else None (the strict path
    decides: it also reads what this refuses, e.g. tabs, or comments after a number).

    The result is sized for the shortest possible row ("0 0 ... 0\\n": 2 bytes a number) in an
    anonymous mapping, not np.empty: its pages are committed 4 KB at a time as rows are written,
    so the unused tail costs address space only (numpy asks for 2 MB huge pages, which would
    commit up to 2 MB past the end of each column: +16 MB a TUM file)."""
    try:
        from mrnc_eval.io import _numtext
    except ImportError:
        return None
    try:
        info = os.stat(path)
    except OSError:
        return None
    if not stat.S_ISREG(info.st_mode):  # a pipe (`<(zcat gt.tum.gz)`) can be read once: by the strict path
        return None
    cap = info.st_size // (2 * ncols) + 1
    buffer = mmap.mmap(-1, 8 * ncols * cap, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
    rows = _numtext.read_columns(path, buffer, ncols)
    if rows <= 0:
        return None
    return np.frombuffer(buffer, dtype=np.float64).reshape(ncols, cap)[:, :rows]


def _strict_table(path: Path, ncols: int) -> NDArray[np.float64]:
    """(rows, ncols) by pandas' C parser; any problem becomes an InputError naming the line."""
    import pandas as pd

    try:
        df = pd.read_csv(path, sep=" ", header=None, comment="#", engine="c", dtype=np.float64,
                         skip_blank_lines=True, encoding="utf-8-sig")
    except FileNotFoundError as err:
        raise InputError(path, "no such file") from err
    except pd.errors.EmptyDataError as err:
        raise InputError(path, "no poses (the file is empty or only comments)") from err
    except (ValueError, pd.errors.ParserError) as err:
        raise InputError(path, first_bad_line(path, ncols, " ")) from err
    if df.shape[1] != ncols:
        raise InputError(path, first_bad_line(path, ncols, " "))
    arr: NDArray[np.float64] = df.to_numpy()
    if not np.isfinite(arr).all():
        raise InputError(path, first_bad_line(path, ncols, " "))
    return arr


def first_bad_line(path: Path, ncols: int, delimiter: str) -> str:
    """The first line that breaks the format, said plainly (for the error message)."""
    try:
        with path.open(encoding="utf-8-sig", errors="replace") as fh:
            for k, line in enumerate(fh, 1):
                row = line.rstrip("\r\n")
                if not row.strip() or row.startswith("#"):
                    continue
                if delimiter == " " and "\t" in row:
                    return f"line {k} contains a tab; fields must be separated by single spaces"
                parts = row.split(delimiter)
                if delimiter == " " and "" in parts:
                    return f"line {k} has leading, trailing or double spaces"
                if ncols > 0 and len(parts) != ncols:
                    return f"line {k} has {len(parts)} fields, expected {ncols}"
                for x in parts:
                    try:
                        if not math.isfinite(float(x)):
                            return f"line {k} has a non-finite value ({x[:20]!r})"
                    except ValueError:
                        return f"line {k} is not numeric ({x[:20]!r})"
    except OSError:
        pass
    return "see the first rows"
