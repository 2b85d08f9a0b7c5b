"""A compiled parser for space-separated numeric text (TUM, KITTI): the fast path of
`trajectory_files`, faster than pandas' C parser and without its intermediate buffers.

The file is read in blocks of whole lines and parsed by a numba kernel straight into the
output array (this module imports numba: import it only when parsing). It accepts only the
plain form (rows of exactly `ncols` numbers separated by single spaces, `#` comment lines,
blank lines, LF or CRLF) and numbers it can convert exactly: significant digits forming an
integer m <= 2^53 (TUM's 16-digit stamps included) with a decimal exponent within +-22
(then m * 10^e or m / 10^-e is one correctly rounded IEEE operation, Clinger 1990), so the
values are bit-identical to strtod's and evo's. Anything else (more digits, "nan", a
malformed line) returns None and the caller falls back to the strict pandas path, which
parses the file or names the bad line.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

BLOCK_BYTES = 1 << 20  # read size; memory stays ~two blocks beyond the output
_POW10 = np.array([10.0 ** k for k in range(23)])  # exact doubles


@njit(cache=True, nogil=True)
def _digits(buf: Any, i: int, n: int, mant: int, ndig: int) -> tuple[int, int, int, int, bool]:  # pragma: no cover
    """Digits from buf[i]: (next i, mantissa, significant digits, digits read, ok)."""
    count = 0
    while i < n and 48 <= buf[i] <= 57:
        d = buf[i] - 48
        if mant != 0 or d != 0:
            if ndig >= 18:  # would overflow int64: not the plain form
                return i, mant, ndig, count, False
            mant = mant * 10 + d
            ndig += 1
        count += 1
        i += 1
    return i, mant, ndig, count, True


@njit(cache=True, nogil=True)
def _number(buf: Any, i: int, n: int, pow10: Any) -> tuple[float, int, bool]:  # pragma: no cover
    """One number from buf[i]: (value, next i, ok); ok is False outside the exact form."""
    neg = i < n and buf[i] == 45
    if i < n and (buf[i] == 45 or buf[i] == 43):
        i += 1
    i, mant, ndig, whole, ok = _digits(buf, i, n, 0, 0)
    frac = 0
    if ok and i < n and buf[i] == 46:  # '.'
        i, mant, ndig, frac, ok = _digits(buf, i + 1, n, mant, ndig)
    exp10 = -frac
    if not ok or whole + frac == 0:
        return 0.0, i, False
    if i < n and (buf[i] == 101 or buf[i] == 69):  # 'e' 'E'
        eneg = i + 1 < n and buf[i + 1] == 45
        i += 2 if i + 1 < n and (buf[i + 1] == 45 or buf[i + 1] == 43) else 1
        i, e, _, edig, ok = _digits(buf, i, n, 0, 0)
        if not ok or edig == 0:
            return 0.0, i, False
        exp10 += -e if eneg else e
    if mant == 0:
        v = 0.0
    elif mant > 9007199254740992 or exp10 > 22 or exp10 < -22:
        return 0.0, i, False
    elif exp10 >= 0:
        v = float(mant) * pow10[exp10]
    else:
        v = float(mant) / pow10[-exp10]
    return (-v if neg else v), i, True


@njit(cache=True, nogil=True)
def _parse_block(buf: Any, n: int, out: Any, row: int, ncols: int, pow10: Any) -> int:  # pragma: no cover
    """Parse buf[:n] (whole lines) into out[:, row:] (one row of `out` per column); the next
    row, or -1 when a line is not in the plain form (the caller falls back)."""
    i = 0
    while i < n:
        c = buf[i]
        if c == 35:  # '#': a comment line
            while i < n and buf[i] != 10:
                i += 1
            i += 1
        elif c == 10 or (c == 13 and i + 1 < n and buf[i + 1] == 10):  # a blank line
            i += 1 if c == 10 else 2
        else:
            if row >= out.shape[1]:
                return -1
            for col in range(ncols):
                v, i, ok = _number(buf, i, n, pow10)
                if not ok:
                    return -1
                out[col, row] = v
                c = buf[i] if i < n else 10
                if col < ncols - 1:
                    if c != 32:  # exactly one space between fields
                        return -1
                    i += 1
                elif c == 13 and i + 1 < n and buf[i + 1] == 10:
                    i += 2
                elif c == 10:
                    i += 1
                else:
                    return -1
            row += 1
    return row


def parse_plain(path: Path, ncols: int) -> NDArray[np.float64] | None:
    """(ncols, rows) float64 of a plain numeric text file, one contiguous row per column (so
    stamps, positions and quaternions are views, not copies), or None to fall back."""
    size = path.stat().st_size
    with path.open("rb") as fh:  # upper bound on rows: newlines + 1
        rows = 1 + sum(np.count_nonzero(np.frombuffer(block, np.uint8) == 10)
                       for block in iter(lambda: fh.read(BLOCK_BYTES), b""))
    out = np.empty((ncols, rows))
    row, carry = 0, b""
    with path.open("rb") as fh:
        first = True
        while True:
            block = fh.read(BLOCK_BYTES)
            data = carry + block
            if first and data.startswith(b"\xef\xbb\xbf"):
                data = data[3:]
            first = False
            if not block:
                cut = len(data)
                if cut and not data.endswith(b"\n"):
                    data += b"\n"
                    cut += 1
            else:
                cut = data.rfind(b"\n") + 1
            if cut:
                row = _parse_block(np.frombuffer(data, np.uint8), cut, out, row, ncols, _POW10)
                if row < 0:
                    return None
            carry = data[cut:]
            if not block:
                break
    if row == 0 or size == 0:
        return None
    return out[:, :row] if row < rows else out
