"""TUM text reading: numbers as float() reads them, a bad line named."""

from __future__ import annotations

from pathlib import Path

import pytest

from mrnc_eval.errors import InputError
from mrnc_eval.io.trajectory_files import read_tum


def test_long_numbers_read_and_bad_lines_named(tmp_path: Path) -> None:
    path = tmp_path / "t.tum"
    path.write_text("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 0.12345678901234567890\n")  # 20 digits: pandas parses it
    assert read_tum(path).quat_xyzw[1, 3] == float("0.12345678901234567890")
    path.write_text("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0\n")
    with pytest.raises(InputError, match="line 2 has 7 fields, expected 8"):
        read_tum(path)
