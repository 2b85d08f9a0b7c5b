"""A ROS 2 MCAP file's ros2msg schemas read as plain field lists, when they are plainly written.

Why: parsing every schema with rosbags' grammar and registering the types takes ~30 ms of a `slam`
run's start (with importing rosbags' typesys), while such a run decodes no message through rosbags
(io/small_msgs.py, io/pose_msg.py, io/cloud_msg.py, io/fast_imu.py read them). What it needs from
the schemas is whether NavSatFix, TFMessage and JointState are defined as standard; for that, a
schema written the way ROS 2's recorder writes it is read here: a definition, then each type it
holds after a line of 80 "=" and "MSG: pkg/Name", every line a field (`type name`, an optional
numeric default) or a constant (`type NAME=value`), comments after "#".

Anything else in any schema of the file (an IDL schema, a bounded or unknown type spelling, a field
or type name not spelled as rosbags' grammar spells names, a default that is not a number, a line
break other than "\n" or a character other than printable ASCII, space and tab outside a comment,
a type defined twice differently) makes `definitions` return None, and the file's schemas are then parsed by rosbags
when it is opened, as before. Everything accepted here is valid in rosbags' grammar too, so a file
it accepts would also have opened with rosbags (tests/io/test_msg_text.py checks both readings on
the project's logs).
"""

from __future__ import annotations

import re
from typing import Any

SEPARATOR = "=" * 80
_BASE = {"bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64",
         "float32", "float64", "string"}
# names as rosbags' msg grammar spells them (package: lower snake case, type: mixed camel case, constant:
# upper snake case; no "__", no trailing "_"), each written with one way to match (linear time)
_TYPE = re.compile(r"(?:([a-z][a-z0-9]*(?:_[a-z0-9]+)*)/(msg/)?)?([A-Za-z][A-Za-z0-9]*(?:_[A-Za-z0-9]+)*)(\[[0-9]*\])?")
_FIELD = re.compile(r"[a-z][a-z0-9_]*")
_CONSTANT = re.compile(r"([a-z][a-z0-9]*)[ \t]+([A-Z][A-Z0-9]*(?:_[A-Z0-9]+)*)[ \t]*=[ \t]*(.*)")
_NUMBER = re.compile(r"[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?")
_INTEGER = re.compile(r"[-+]?[0-9]+")
_ODD_CHAR = re.compile(r"[^\x21-\x7e \t]")  # outside comments: rosbags' grammar reads no other (\r, \f, unicode)
_SPACE = re.compile(r"[ \t]+")

Fields = tuple[tuple[str, str], ...]  # ((field name, type), ...): "float64", "pkg/msg/Name", "type[9]", "type[]"


def _full_name(name: str) -> str | None:
    """pkg/msg/Name for pkg/Name or pkg/msg/Name; None for anything else."""
    full = _type(name)
    return None if full is None or "/" not in full or full.endswith("]") else full


def _type(word: str) -> str | None:
    """A base type or pkg/msg/Name, with its array suffix; None for anything else (rosbags reads a
    package named like a base type, "uint8/Foo", as that base type and then fails)."""
    match = _TYPE.fullmatch(word)
    if match is None:
        return None
    package, name, suffix = match.group(1), match.group(3), match.group(4) or ""
    if package is None:
        return name + suffix if name in _BASE else None
    return None if package in _BASE else f"{package}/msg/{name}{suffix}"


def _plain_constant(typ: str, value: str) -> bool:
    """A constant of a number type with a number of its kind, or a string constant."""
    if typ == "string":
        return True
    if typ in ("float32", "float64"):
        return bool(_NUMBER.fullmatch(value))
    return typ in _BASE and typ != "bool" and bool(_INTEGER.fullmatch(value))


def _fields(body: str) -> Fields | None:
    """A definition's fields (constants skipped), or None when a line is not plainly a field or a constant."""
    out: list[tuple[str, str]] = []
    for line in body.split("\n"):
        text = line.split("#", 1)[0]
        if _ODD_CHAR.search(text):
            return None
        text = text.strip(" \t")
        if not text:
            continue
        constant = _CONSTANT.fullmatch(text)
        if constant is not None:
            if not _plain_constant(constant.group(1), constant.group(3)):
                return None
            continue
        words = _SPACE.split(text)
        typ = _type(words[0])
        if typ is None or len(words) not in (2, 3) or not _FIELD.fullmatch(words[1]) \
                or (len(words) == 3 and not _NUMBER.fullmatch(words[2])):
            return None
        out.append((words[1], typ))
    return tuple(out)


def _schema(text: str, name: str) -> dict[str, Fields] | None:
    """Every type one schema defines: `name` first, then each "MSG:" section."""
    parts = text.split("\n" + SEPARATOR + "\n")
    defined: dict[str, Fields] = {}
    for k, part in enumerate(parts):
        head, _, body = part.partition("\n") if k else ("MSG: " + name, "", part)
        full = _full_name(head[5:].rstrip(" \t")) if head.startswith("MSG: ") else None
        fields = _fields(body)
        if full is None or fields is None or defined.get(full, fields) != fields:
            return None
        defined[full] = fields
    return defined


def definitions(summary: Any) -> dict[str, Fields] | None:
    """type -> its fields over all the schemas of an mcap Summary, or None unless every schema is
    a plainly written ros2msg one and no type is defined two ways."""
    out: dict[str, Fields] = {}
    for schema in summary.schemas.values():
        if schema.encoding != "ros2msg":
            return None
        try:
            defined = _schema(schema.data.decode(), schema.name)
        except UnicodeDecodeError:
            return None
        if defined is None:
            return None
        for name, fields in defined.items():
            if out.setdefault(name, fields) != fields:
                return None
    return out
