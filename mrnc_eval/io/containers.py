"""Which container a path is, and opening it with the right library.

A file is recognised by its first bytes, its suffix only when those say nothing (a truncated
file, an unknown format):
  #ROSBAG V2.0 (*.bag; several: a split recording) -> ROS 1 (rosbags)
  directory with metadata.yaml                     -> ROS 2 bag (sqlite3 or MCAP storage)
  SQLite format 3 (*.db3)                           -> ROS 2 sqlite3 single file
  MCAP magic (*.mcap) with ROS 2 profile/encodings  -> ROS 2 MCAP single file (rosbags)
  MCAP magic otherwise                              -> plain MCAP (mcap library): ROS 1 and CDR
                                                       channels are decoded, others refused when read
rosbags itself picks its reader by suffix: `openable` gives it links with the right one.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from mrnc_eval.errors import InputError
from mrnc_eval.io.library_errors import data_errors

LOG_SUFFIXES = (".mcap", ".db3", ".bag")  # single-file logs; a ROS 2 bag may also be a folder
SUPPORTED = "a ROS 1 .bag, a ROS 2 bag directory (metadata.yaml), a .db3 or an .mcap file"
# the writers' formats (`simulate --format`, io.writers.LogWriter) and the suffix each one's file has
FORMAT_SUFFIX = {"bag": ".bag", "mcap": ".mcap", "db3": ".db3"}
SUFFIX_FORMAT = {suffix: fmt for fmt, suffix in FORMAT_SUFFIX.items()}
FORMAT_NAMES = {"bag": "ROS 1 bag", "mcap": "ROS 2 MCAP", "db3": "ROS 2 sqlite3"}
MAGIC = ((b"#ROSBAG V2.0", "ros1"), (b"\x89MCAP0\r\n", "mcap"), (b"SQLite format 3\x00", "ros2-sqlite3"))
SUFFIX_CONTAINER = {".bag": "ros1", ".mcap": "mcap", ".db3": "ros2-sqlite3"}
CONTAINER_SUFFIX = {"ros1": ".bag", "ros2-mcap": ".mcap", "ros2-sqlite3": ".db3"}  # what rosbags needs to see


def describe_error(err: BaseException) -> str:
    """A library exception as one short line (its text, or its type when it has none)."""
    text = " ".join(str(err).split())
    text = text or type(err).__name__
    return text if len(text) <= 300 else text[:297] + "..."


def sniff(path: Path) -> str | None:
    """ros1, mcap or ros2-sqlite3 by the file's first bytes; None when they say none of these."""
    try:
        with path.open("rb") as fh:
            head = fh.read(16)
    except OSError:
        return None
    return next((kind for magic, kind in MAGIC if head.startswith(magic)), None)


def is_log_file(path: Path) -> bool:
    """A single-file log, by its first bytes or its suffix."""
    return path.is_file() and (sniff(path) is not None or path.suffix.lower() in LOG_SUFFIXES)


def _folder_problem(folder: Path) -> str:
    """Why a folder is not a log: a folder of logs points to `nightly` or a glob (the user meant
    every log in it); anything else says what a log is."""
    try:
        inside = sorted(p for p in folder.iterdir() if not p.name.startswith(".")
                        and (is_log_file(p) or (p / "metadata.yaml").is_file()))
    except OSError:
        inside = []
    if not inside:
        return f"directory is not a ROS 2 bag (no metadata.yaml); expected {SUPPORTED}"
    suffixes = sorted({p.suffix for p in inside if p.is_file() and p.suffix})
    globs = " ".join(f"{folder}/*{s}" for s in suffixes) or f"{folder}/*"
    return (f"a folder of {len(inside)} log(s), not one log (a ROS 2 bag folder holds metadata.yaml): "
            f"`mrnc-eval nightly {folder} --out REPORTS` processes every log in it, or name them, e.g. {globs}")


def detect_container(paths: list[Path]) -> str:
    first = paths[0]
    for p in paths:
        if not p.exists():
            raise InputError(p, "no such file or directory")
    if first.is_dir():
        meta = first / "metadata.yaml"
        if not meta.exists():
            raise InputError(first, _folder_problem(first))
        return "ros2-mcap" if _bag_storage(meta) == "mcap" else "ros2-sqlite3"
    if len(paths) > 1:  # a split recording: every file of the same kind
        kinds = {p: detect_container([p]) for p in paths}
        if len(set(kinds.values())) > 1:
            listed = ", ".join(f"{p.name} ({k})" for p, k in kinds.items())
            raise InputError(first, f"the files of a split log must be of one kind: {listed}")
        return kinds[first]
    kind = sniff(first) or SUFFIX_CONTAINER.get(first.suffix.lower())
    if kind is None:
        raise InputError(first, f"unrecognised log format; expected {SUPPORTED}")
    if kind == "mcap":
        return "ros2-mcap" if _mcap_is_ros2(first) else "mcap"
    return kind


@contextmanager
def openable(paths: list[Path], container: str) -> Iterator[list[Path]]:
    """`paths` as rosbags can open them. rosbags picks its reader by suffix (ROS 1 for anything
    named .bag, a folder included), so a file whose suffix does not say what its first bytes say,
    or a ROS 2 bag folder named x.bag (what `simulate x.bag` wrote before), is opened through a
    link with the right name, in a temporary folder removed on exit."""
    want = CONTAINER_SUFFIX.get(container)

    def misnamed(p: Path) -> bool:
        return p.suffix == ".bag" if p.is_dir() else want is not None and p.suffix != want

    if not any(misnamed(p) for p in paths):
        yield paths
        return
    links = Path(tempfile.mkdtemp(prefix=".mrnc-open-"))
    try:
        named = []
        for k, p in enumerate(paths):
            if not misnamed(p):
                named.append(p)
                continue
            named.append(links / f"{k}-{p.stem or 'log'}{'' if p.is_dir() else want}")
            named[-1].symlink_to(p.resolve(), target_is_directory=p.is_dir())
        yield named
    finally:
        shutil.rmtree(links, ignore_errors=True)


def _bag_storage(meta: Path) -> str:
    """storage_identifier of a ROS 2 bag's metadata.yaml ("" when it cannot be read: rosbags
    then reports the problem when opening the bag)."""
    import yaml

    try:
        info = yaml.safe_load(meta.read_text(encoding="utf-8", errors="replace"))
        return str(info["rosbag2_bagfile_information"]["storage_identifier"])
    except (OSError, yaml.YAMLError, KeyError, TypeError):  # unreadable, not YAML, not a bag's metadata
        return ""


def _mcap_is_ros2(path: Path) -> bool:
    from mrnc_eval.io import mcap_summary

    try:  # the header alone, without the mcap library (io/mcap_summary.py); anything odd: the library's reading
        if mcap_summary.profile(path) == "ros2":
            return True
    except (mcap_summary.Unreadable, OSError):
        pass
    from mcap.reader import make_reader

    try:
        with path.open("rb") as fh:
            reader = make_reader(fh)
            header = reader.get_header()
            if header.profile == "ros2":
                return True
            summary = reader.get_summary()
    except data_errors() as err:  # McapError, struct.error, EOFError, decompression errors...
        raise InputError(path, f"not a readable MCAP file: {describe_error(err)}") from err
    if summary is None:
        return False
    schemas = summary.schemas
    return bool(summary.channels) and all(
        ch.message_encoding == "cdr" and schemas.get(ch.schema_id) is not None
        and schemas[ch.schema_id].encoding in ("ros2msg", "ros2idl")
        for ch in summary.channels.values()
    )

