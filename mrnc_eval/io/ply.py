"""The vertices of a PLY point cloud (the SLAM's map.ply) without open3d: header, then the
vertex element as a numpy structured array (binary little/big endian or ASCII)."""

from __future__ import annotations

from pathlib import Path
from typing import BinaryIO

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.errors import InputError

_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
          "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
          "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
MAX_HEADER_LINES = 200


def _header(fh: BinaryIO, path: Path) -> tuple[str, int, list[tuple[str, str]]]:
    """format, vertex count and vertex properties (name, numpy type); leaves `fh` at the body."""
    if fh.readline().strip() != b"ply":
        raise InputError(path, "not a PLY file")
    fmt, count, current = "", 0, ""
    props: list[tuple[str, str]] = []
    for _ in range(MAX_HEADER_LINES):
        words = fh.readline().decode("ascii", "replace").split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "end_header":
            return fmt, count, props
        if words[0] == "format":
            fmt = words[1]
        elif words[0] == "element":
            current = words[1]
            count = int(words[2]) if current == "vertex" else count
        elif words[0] == "property" and current == "vertex":
            if words[1] == "list" or words[1] not in _TYPES:
                raise InputError(path, f"vertex property {' '.join(words[1:])!r} is not supported")
            props.append((words[2], _TYPES[words[1]]))
    raise InputError(path, "PLY header without end_header")


def read_ply_xyz(path: Path) -> NDArray[np.float64]:
    """(N, 3) vertex positions; InputError naming the file when it is not a PLY this reads
    (list properties on the vertex element, a truncated body)."""
    with open(path, "rb") as fh:
        fmt, count, props = _header(fh, path)
        if not {"x", "y", "z"} <= {n for n, _ in props}:
            raise InputError(path, "PLY vertices without x, y, z")
        if fmt == "ascii":
            table = np.loadtxt(fh, max_rows=count, ndmin=2)
            names = [n for n, _ in props]
            cols = [names.index(a) for a in "xyz"]
            if table.shape[0] != count:
                raise InputError(path, f"PLY body has {table.shape[0]} of {count} vertices")
            return np.ascontiguousarray(table[:, cols], dtype=np.float64)
        order = {"binary_little_endian": "<", "binary_big_endian": ">"}.get(fmt)
        if order is None:
            raise InputError(path, f"unknown PLY format {fmt!r}")
        dtype = np.dtype([(n, order + t) for n, t in props])
        data = np.fromfile(fh, dtype=dtype, count=count)
    if data.shape[0] != count:
        raise InputError(path, f"PLY body has {data.shape[0]} of {count} vertices (truncated)")
    return np.column_stack([data[a].astype(np.float64) for a in "xyz"])


def write_ply_xyz(path: Path, points: NDArray[np.floating]) -> None:
    """(N, 3) positions as a binary little-endian PLY with double x, y, z (the layout open3d writes
    for a cloud without colours or normals, so readers of the old map.ply read the same values)."""
    xyz = np.ascontiguousarray(points, dtype="<f8").reshape(-1, 3)
    header = (f"ply\nformat binary_little_endian 1.0\ncomment Created by mrnc-eval\nelement vertex {len(xyz)}\n"
              "property double x\nproperty double y\nproperty double z\nend_header\n")
    with open(path, "wb") as fh:
        fh.write(header.encode("ascii"))
        xyz.tofile(fh)
