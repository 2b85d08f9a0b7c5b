"""TUM text reading: numbers as float() reads them, a bad line named; the fast C reader reads
plain files exactly as the strict path (pandas) does and hands everything else to it."""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mrnc_eval.io
from mrnc_eval.errors import InputError
from mrnc_eval.io import number_table
from mrnc_eval.io.trajectory_files import read_tum
from tests.c_build import build_extension

SOURCE = Path(number_table.__file__).with_name("_numtext.c")


@pytest.fixture(scope="module")
def numtext(tmp_path_factory: pytest.TempPathFactory) -> ModuleType:
    """The C reader built from this tree's source (an installed build may be older, and a
    worktree run from PYTHONPATH has none); with CI=true a missing compiler fails."""
    return build_extension(SOURCE, "mrnc_eval.io._numtext", tmp_path_factory.mktemp("numtext"),
                           ("-O2",))


@pytest.fixture
def with_numtext(numtext: ModuleType, monkeypatch: pytest.MonkeyPatch) -> None:
    """number_table uses the reader built from this tree's source."""
    monkeypatch.setitem(sys.modules, "mrnc_eval.io._numtext", numtext)
    monkeypatch.setattr(mrnc_eval.io, "_numtext", numtext, raising=False)


def test_long_numbers_read_and_bad_lines_named(tmp_path: Path) -> None:
    path = tmp_path / "t.tum"
    path.write_text("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 0.12345678901234567890\n")  # 20 digits: pandas parses it
    assert read_tum(path).quat_xyzw[1, 3] == float("0.12345678901234567890")
    path.write_text("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0\n")
    with pytest.raises(InputError, match="line 2 has 7 fields, expected 8"):
        read_tum(path)


ROW = "1305031102.175304 1.2 -0.5 0.25 0.1 -0.2 0.3 0.9"


@pytest.mark.usefixtures("with_numtext")
@pytest.mark.parametrize(("text", "fast"), [
    (f"{ROW}\n{ROW}\n", True),
    (f"# timestamp tx ty tz qx qy qz qw\n# file: 'rgbd_dataset'\n\n{ROW}\r\n{ROW}", True),  # TUM RGB-D's head
    (f"\ufeff{ROW}\n\n{ROW}\n# a comment between rows\n{ROW}\n", True),
    (f"{ROW}\n# café: not ASCII\n{ROW}\n", False),
    (f"{ROW}\n{ROW} # a comment after numbers\n", False),
    (f"{ROW}\n{ROW}\t\n", False),
    (f"{ROW}\n{ROW}\r{ROW}\n", False),  # a lone CR ends a line for pandas
    (f"{ROW}\n" + "0  1 2 3 4 5 6 7\n", False),  # double space: the strict path names it
    (f"{ROW}\n" + "0 1 2 3 4 5 6 1e999\n", False),
])
def test_fast_path_takes_plain_files_only(tmp_path: Path, text: str, fast: bool) -> None:
    path = tmp_path / "t.tum"
    path.write_text(text, encoding="utf-8")
    got = number_table._fast_columns(path, 8)
    assert (got is not None) is fast
    if got is not None:
        np.testing.assert_array_equal(got, number_table._strict_table(path, 8).T)
        assert got[0, 0] == float("1305031102.175304")


def test_fast_path_rounds_as_float(tmp_path: Path, numtext: ModuleType) -> None:
    """Clinger's exact case, 19+ digits, exponents, subnormals: every value as float() reads it."""
    rng = np.random.default_rng(1)
    tokens = ["0", "-0", "5.", ".5", "+1.25", "007", "0.12345678901234567890", "9007199254740993", "1e22", "1E-5",
              "123456789012345678901234", "2.5e+300", "4.9e-324", "1e-400", "0.1000000000000000055511151231257827",
              # around the one-pass reader's limits: 19 digits counting leading zeros, 2^53, 22 decimals
              "00000000000000000001.5", "0.0000000000000000001234", "-0.0000000000000000000000001",
              "1234567890123456789", "9007199254740992", "9007199254740992.1", "0.1234567890123456789",
              *(repr(float(x)) for x in rng.normal(scale=1e6, size=60)), *(f"{x:.17g}" for x in rng.uniform(-1, 1, 60))]
    tokens += ["1"] * (-len(tokens) % 8)
    path = tmp_path / "n.txt"
    path.write_text("\n".join(" ".join(tokens[k:k + 8]) for k in range(0, len(tokens), 8)) + "\n")
    out = np.empty((8, len(tokens)))
    rows = numtext.read_columns(path, out, 8)
    assert rows == len(tokens) // 8
    got = out[:, :rows].T.ravel()
    assert got.tobytes() == np.array([float(t) for t in tokens]).tobytes()


def test_fast_path_reads_across_blocks(tmp_path: Path, with_numtext: None) -> None:
    """Rows straddle the 1 MB read blocks; a line longer than a block goes to the strict path."""
    rng = np.random.default_rng(2)
    table = rng.normal(size=(40_000, 8))
    path = tmp_path / "big.tum"
    np.savetxt(path, table, fmt="%.17g", header="x", comments="# ")
    got = number_table._fast_columns(path, 8)
    assert got is not None
    assert got.T.tobytes() == table.tobytes()
    path.write_text("#" + "x" * (1 << 20) + "\n" + ROW + "\n")
    assert number_table._fast_columns(path, 8) is None
    assert number_table.read_columns(path, 8)[0, 0] == float("1305031102.175304")


def _outcome(path: Path, read: Callable[[Path, int], np.ndarray]) -> tuple[str, object]:
    try:
        return "ok", np.asarray(read(path, 8)).tobytes()
    except InputError as err:
        return "error", str(err)


PIECES = [" ", "  ", "\t", "\n", "\r\n", "\r", "#", "# c\n", "nan", "inf", "1e400", "e", "E5", "-", "+", ".", "x",
          '"', "\ufeff", "\x0b", "\x00", "é", "7", "0.125", ""]


@pytest.mark.usefixtures("with_numtext")
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rows=st.lists(st.lists(st.floats(-1e4, 1e4), min_size=8, max_size=8), min_size=1, max_size=4),
       edits=st.lists(st.tuples(st.integers(0, 10_000), st.sampled_from(PIECES), st.booleans()), max_size=3),
       head=st.booleans())
def test_fast_path_reads_like_the_strict_path(tmp_path: Path, rows: list[list[float]],
                                              edits: list[tuple[int, str, bool]], head: bool) -> None:
    """Damaged and undamaged files: the same bits, or the same error naming the same line."""
    text = ("# t x y z qx qy qz qw\n" if head else "") + "\n".join(" ".join(map(repr, r)) for r in rows) + "\n"
    for at, piece, replace in edits:  # insert a piece, or put it in place of one character
        k = at % (len(text) + 1)
        text = text[:k] + piece + text[k + replace:]
    path = tmp_path / "f.tum"
    path.write_bytes(text.encode("utf-8"))
    strict = _outcome(path, lambda p, n: number_table._strict_table(p, n).T)
    assert _outcome(path, number_table.read_columns) == strict


@pytest.mark.timeout(30)  # opening the pipe without a writer blocks: that failure must not take 15 minutes
def test_a_pipe_is_read_once_by_the_strict_path(tmp_path: Path, with_numtext: None) -> None:
    """`ape <(zcat gt.tum.gz) est.tum`: the fast path must not consume the stream."""
    fifo = tmp_path / "gt.fifo"
    os.mkfifo(fifo)
    assert number_table._fast_columns(fifo, 8) is None  # returns without opening it (would block)

    def write() -> None:
        fifo.write_text(f"{ROW}\n{ROW}\n")

    writer = threading.Thread(target=write)
    writer.start()
    cols = number_table.read_columns(fifo, 8)
    writer.join()
    assert cols.shape == (8, 2)
