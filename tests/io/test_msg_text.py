"""A ROS 2 MCAP file's ros2msg schemas read as field lists (io/msg_text.py) against rosbags'
parser: the same fields of every type on the project's logs and on plainly written variants
(comments, defaults, constants, spacing); None, so that rosbags parses the file when it is
opened as before, for anything not plainly written."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from mrnc_eval.io import msg_text, small_msgs
from mrnc_eval.io.ros2_mcap import Ros2McapSource, read_summary
from tests.io.test_io_roundtrip import write_sample

REPO = Path(__file__).resolve().parents[2]
SEP = msg_text.SEPARATOR


def _rosbags_fields(types: Any) -> dict[str, msg_text.Fields]:
    return {name: tuple((str(f), small_msgs._field_type(d)) for f, d in types[name][1]) for name in types}


def _both(path: Path) -> tuple[dict[str, msg_text.Fields] | None, dict[str, msg_text.Fields]]:
    """Our reading, and rosbags' of the same schemas (less the types its empty store starts with)."""
    from rosbags.typesys import Stores, get_typestore

    summary = read_summary(path)
    theirs = _rosbags_fields(Ros2McapSource(path, summary)._typestore().fielddefs)
    builtin = set(get_typestore(Stores.EMPTY).fielddefs)
    ours = msg_text.definitions(summary)
    return ours, {k: v for k, v in theirs.items() if k not in builtin or (ours is not None and k in ours)}


def test_the_sample_log_reads_as_rosbags_parses_it() -> None:
    ours, theirs = _both(REPO / "sample_logs" / "circle_soft_ground.mcap")
    assert ours is not None
    assert ours == theirs
    assert len(ours) > 20


def test_the_real_recording_reads_as_rosbags_parses_it(real_ouster_mcap: Path) -> None:
    ours, theirs = _both(real_ouster_mcap)
    assert ours == theirs


def test_a_written_log_reads_as_rosbags_parses_it(tmp_path: Path) -> None:
    write_sample(tmp_path / "log.mcap", "mcap")
    ours, theirs = _both(tmp_path / "log.mcap")
    assert ours == theirs


def _summary(*schemas: tuple[str, str, str]) -> SimpleNamespace:
    """An mcap Summary stand-in: (name, encoding, text) per schema."""
    return SimpleNamespace(schemas={k: SimpleNamespace(name=n, encoding=e, data=t.encode())
                                    for k, (n, e, t) in enumerate(schemas, 1)})


QUATERNION = "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
PLAIN_VARIANTS = [
    "# a comment line\nuint8 KIND_A=1  # kind\nfloat64 x # metres\n  float64   y\n\nstring s\n",
    "int8 LOW=-1\nfloat32 GAIN=1.5e-3\nstring NAME=a b # c\nfloat64[9] cov\nstring[] names\nint32[] v\n",
    "geometry_msgs/Quaternion q\n" + SEP + "\nMSG: geometry_msgs/Quaternion\n" + QUATERNION,
]


@pytest.mark.parametrize("text", PLAIN_VARIANTS)
def test_plainly_written_variants_read_as_rosbags_parses_them(text: str) -> None:
    from rosbags.typesys import get_types_from_msg

    ours = msg_text.definitions(_summary(("test_msgs/msg/T", "ros2msg", text)))
    assert ours is not None
    assert ours == _rosbags_fields(get_types_from_msg(text, "test_msgs/msg/T"))


NOT_PLAIN = [
    ("ros2idl", "module test_msgs { module msg { struct T { double x; }; }; };"),
    ("ros2msg", "string<=5 s\n"),  # bounded
    ("ros2msg", "float64[<=3] v\n"),
    ("ros2msg", "Header header\n"),  # a type without its package
    ("ros2msg", "float64 X\n"),  # not a field name
    ("ros2msg", "string s 'text'\n"),  # a default that is not a number
    ("ros2msg", "bool FLAG=true\n"),
    ("ros2msg", "int8 K=1.5\n"),
    ("ros2msg", "time t\n"),  # ROS 1's
    ("ros2msg", "float64 x\n" + SEP + "\nNOT: pkg/Name\nfloat64 y\n"),
    ("ros2msg", "pkg/Name n\n" + SEP + "\nMSG: pkg/Na\0\0me\nfloat64 y\n"),  # rosbags' grammar refuses it
    ("ros2msg", "pkg/Name n\n" + SEP + "\nMSG: pkg/Na me\nfloat64 y\n"),
]


@pytest.mark.parametrize(("encoding", "text"), NOT_PLAIN)
def test_what_is_not_plainly_written_is_left_to_rosbags(encoding: str, text: str) -> None:
    assert msg_text.definitions(_summary(("test_msgs/msg/T", encoding, text))) is None


def test_a_type_defined_two_ways_is_left_to_rosbags() -> None:
    """rosbags keeps the definition of the schema registered last: not decided here."""
    a = "pkg/Point p\n" + SEP + "\nMSG: pkg/Point\nfloat64 x\n"
    b = "pkg/Point p\n" + SEP + "\nMSG: pkg/Point\nfloat32 x\n"
    assert msg_text.definitions(_summary(("pkg/msg/A", "ros2msg", a), ("pkg/msg/B", "ros2msg", a))) is not None
    assert msg_text.definitions(_summary(("pkg/msg/A", "ros2msg", a), ("pkg/msg/B", "ros2msg", b))) is None


def test_a_long_number_in_a_schema_is_read_in_linear_time() -> None:
    """A schema line is text from the file: 20,000 digits and a letter (not a number) took ~7 s
    CPU with a backtracking number pattern (quadratic; a 1 MB line: hours)."""
    import time

    digits = "1" * 20_000
    text = f"float64 X={digits}x\nfloat64 y {digits}.{digits}e{digits}x\n"
    start = time.process_time()
    assert msg_text.definitions(_summary(("test_msgs/msg/T", "ros2msg", text))) is None
    assert time.process_time() - start < 0.5
    plain = f"float64 X={digits}.{digits}e-{digits}\nfloat64 y -{digits}.\n"  # the negative control: numbers
    ours = msg_text.definitions(_summary(("test_msgs/msg/T", "ros2msg", plain)))
    assert ours == {"test_msgs/msg/T": (("y", "float64"),)}


REFUSED_BY_ROSBAGS = [
    "float64 x\r\nfloat64 y\n",  # CRLF
    "float64 x\x0cfloat64 y\n",  # a form feed: a line break to str.splitlines
    "float64\u00a0x\n",  # a no-break space: a space to str.split
    "int32 A_=1\n",  # a constant name ending in "_"
    "uint8/Foo f\n",  # a package named like a base type
    "geometrY_msgs/Twist t\n",  # a package name with a capital
    "pkg/Na__me n\n",
    "pkg/Name n\n" + SEP + "\nMSG:  pkg/Name\nfloat64 y\n",  # two spaces after "MSG:"
]


@pytest.mark.parametrize("text", REFUSED_BY_ROSBAGS)
def test_what_rosbags_grammar_refuses_is_never_read_here(text: str) -> None:
    """Else a file AnyReader refuses would open through io/ros2_mcap.py (found by fuzzing the
    sample log's summary: one changed byte in a schema)."""
    from rosbags.typesys import TypesysError, get_types_from_msg

    with pytest.raises(TypesysError):  # the negative control: rosbags refuses each
        get_types_from_msg(text, "test_msgs/msg/T")
    assert msg_text.definitions(_summary(("test_msgs/msg/T", "ros2msg", text))) is None
