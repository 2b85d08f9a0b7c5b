"""Which container a path is, and opening it with the right library.

An explicit registry keyed by what the path looks like:
  *.bag (one or several split files)      -> ROS 1 (rosbags)
  directory with metadata.yaml           -> ROS 2 bag (sqlite3 or MCAP storage)
  *.db3                                   -> ROS 2 sqlite3 single file
  *.mcap with ROS 2 profile/encodings     -> ROS 2 MCAP single file (rosbags)
  *.mcap otherwise                        -> plain MCAP (mcap library): ROS 1 and CDR channels
                                             are decoded, others refused when read
"""

from __future__ import annotations

from pathlib import Path

from mrnc_eval.errors import InputError

LOG_SUFFIXES = (".mcap", ".db3", ".bag")  # single-file logs; a ROS 2 bag may also be a folder
SUPPORTED = "a ROS 1 .bag, a ROS 2 bag directory (metadata.yaml), a .db3 or an .mcap file"


def describe_error(err: BaseException) -> str:
    """A library exception as one short line (its text, or its type when it has none)."""
    text = " ".join(str(err).split())
    text = text or type(err).__name__
    return text if len(text) <= 300 else text[:297] + "..."


def detect_container(paths: list[Path]) -> str:
    first = paths[0]
    for p in paths:
        if not p.exists():
            raise InputError(p, "no such file or directory")
    if first.is_dir():
        meta = first / "metadata.yaml"
        if not meta.exists():
            raise InputError(first, f"directory is not a ROS 2 bag (no metadata.yaml); expected {SUPPORTED}")
        return "ros2-mcap" if _bag_storage(meta) == "mcap" else "ros2-sqlite3"
    suffix = first.suffix.lower()
    if suffix == ".bag":
        if any(p.suffix.lower() != ".bag" for p in paths):
            raise InputError(first, "split logs must all be ROS 1 .bag files")
        return "ros1"
    if len(paths) > 1:  # a split recording: every file of the same kind
        kinds = {p: detect_container([p]) for p in paths}
        if len(set(kinds.values())) > 1:
            listed = ", ".join(f"{p.name} ({k})" for p, k in kinds.items())
            raise InputError(first, f"the files of a split log must be of one kind: {listed}")
        return kinds[first]
    if suffix == ".db3":
        return "ros2-sqlite3"
    if suffix == ".mcap":
        return "ros2-mcap" if _mcap_is_ros2(first) else "mcap"
    raise InputError(first, f"unrecognised log format; expected {SUPPORTED}")


def _bag_storage(meta: Path) -> str:
    """storage_identifier of a ROS 2 bag's metadata.yaml ("" when it cannot be read: rosbags
    then reports the problem when opening the bag)."""
    import yaml

    try:
        info = yaml.safe_load(meta.read_text(encoding="utf-8", errors="replace"))
        return str(info["rosbag2_bagfile_information"]["storage_identifier"])
    except Exception:
        return ""


def _mcap_is_ros2(path: Path) -> bool:
    from mcap.reader import make_reader

    try:
        with path.open("rb") as fh:
            reader = make_reader(fh)
            header = reader.get_header()
            if header.profile == "ros2":
                return True
            summary = reader.get_summary()
    except Exception as err:  # McapError, struct.error, EOFError, decompression errors...
        raise InputError(path, f"not a readable MCAP file: {describe_error(err)}") from err
    if summary is None:
        return False
    schemas = summary.schemas
    return bool(summary.channels) and all(
        ch.message_encoding == "cdr" and schemas.get(ch.schema_id) is not None
        and schemas[ch.schema_id].encoding in ("ros2msg", "ros2idl")
        for ch in summary.channels.values()
    )

