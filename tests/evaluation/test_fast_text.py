"""The compiled TUM/KITTI parser: values bit-identical to Python's float() (so to evo's),
strict about the form, and falling back (to the pandas path that names the bad line) on
anything it does not convert exactly."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.errors import InputError
from mrnc_eval.io.fast_text import parse_plain
from mrnc_eval.io.trajectory_files import read_tum


def test_values_are_bit_identical_to_float(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    stamps = 1305031102.0 + np.cumsum(rng.uniform(0.001, 0.05, 3000))  # TUM RGB-D: 16 significant digits
    values = rng.normal(scale=50.0, size=(3000, 7))
    rows = [f"{t:.6f} " + " ".join(f"{v:{fmt}}" for v, fmt in zip(row, ["9.4f", ".6e", ".9f", "g", ".12f", "E", "f"],
                                                                   strict=True))
            for t, row in zip(stamps, values, strict=True)]
    rows = [" ".join(r.split()) for r in rows]
    text = "\ufeff# comment\n" + "\r\n".join(rows[:10]) + "\n\n" + "\n".join(rows[10:])  # BOM, CRLF, blank
    path = tmp_path / "t.tum"
    path.write_text(text, encoding="utf-8")
    got = parse_plain(path, 8)
    assert got is not None
    expected = np.array([[float(x) for x in r.split(" ")] for r in rows])
    np.testing.assert_array_equal(got.T, expected)


@pytest.mark.parametrize("line", ["1 2 3 4 5 6 7", "1 2 3 4 5 6 7 8 9", "1  2 3 4 5 6 7 8", "1\t2 3 4 5 6 7 8",
                                  "1 2 3 4 5 6 7 8 ", " 1 2 3 4 5 6 7 8", "1 2 3 4 5 6 7 nan", "1 2 3 x 5 6 7 8",
                                  "1 2 3 4 5 6 7 1e", "1 2 3 4 5 6 7 0.12345678901234567890"])
def test_anything_else_falls_back(tmp_path: Path, line: str) -> None:
    path = tmp_path / "t.tum"
    path.write_text("0 0 0 0 0 0 0 1\n" + line + "\n")
    assert parse_plain(path, 8) is None


def test_fallback_still_reads_or_names_the_line(tmp_path: Path) -> None:
    path = tmp_path / "t.tum"
    path.write_text("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 0.12345678901234567890\n")  # 20 digits: pandas parses it
    assert read_tum(path).quat_xyzw[1, 3] == float("0.12345678901234567890")
    path.write_text("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0\n")
    with pytest.raises(InputError, match="line 2 has 7 fields, expected 8"):
        read_tum(path)
