"""PointCloud2 decoding by field name and datatype (never by fixed offsets).

Supports the Ouster layout (`t` u32 ns since sweep start, `ring` u8/u16, `range`,
`reflectivity`), the Velodyne layout (`time` f32 s relative), and `timestamp` f64
(absolute or relative seconds). No-return points (all-zero or non-finite xyz) are removed
together with their per-point times; point time is normalised to seconds since the
header stamp (the sweep start).
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mrnc_eval.data import Sweep

_gather_c: Callable[..., int] | None
try:  # io/_cloud.c, built by setup.py when a C compiler is there (optional: numpy gives the same arrays)
    from mrnc_eval.io._cloud import gather as _gather_c
except ImportError:
    _gather_c = None
_FLOAT32, _UINT16, _NS_TO_S, _ROW, _COLUMN = range(5)  # io/_cloud.c's column kinds

# sensor_msgs/PointField datatypes -> numpy
_DTYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


class CloudFormatError(ValueError):
    """The cloud's layout cannot be decoded (missing x/y/z, bad sizes)."""


@functools.lru_cache(maxsize=16)
def _cached_dtype(key: tuple[tuple[str, int, int, int], ...], point_step: int, big_endian: bool) -> np.dtype[np.void]:
    fields = [_FieldKey(name=n, offset=o, datatype=d, count=c) for n, o, d, c in key]
    return structured_dtype(fields, point_step, big_endian)


@dataclass(frozen=True, kw_only=True)
class _FieldKey:
    """A cloud field's name, offset and type (the key of a cached layout)."""

    name: str
    offset: int
    datatype: int
    count: int


def structured_dtype(fields: Sequence[Any], point_step: int, big_endian: bool) -> np.dtype[np.void]:
    names, formats, offsets = [], [], []
    order = ">" if big_endian else "<"
    for f in fields:
        if f.datatype not in _DTYPES:
            raise CloudFormatError(f"field {f.name!r} has unknown datatype {f.datatype}")
        if f.count != 1:
            continue  # array fields are not used
        names.append(f.name)
        formats.append(order + _DTYPES[f.datatype])
        offsets.append(f.offset)
    return np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": point_step})


def decode_cloud(msg: Any, stamp: float) -> Sweep:
    """Decode a sensor_msgs/PointCloud2 message into a Sweep (no-return points removed)."""
    names = {f.name for f in msg.fields}
    missing = {"x", "y", "z"} - names
    if missing:
        raise CloudFormatError(f"PointCloud2 has no {'/'.join(sorted(missing))} field(s) (fields: {sorted(names)})")
    height, width = int(msg.height), int(msg.width)
    data, dtype = _layout(msg)
    arrays = _gathered(msg, data, names) or _numpy_arrays(msg, _records(msg, data), dtype, names)
    return Sweep(stamp=stamp, points=arrays["points"], point_time=_time_of(arrays, names, stamp),
                 ring=arrays.get("ring"), column=arrays.get("column"), intensity=arrays.get("intensity"),
                 reflectivity=arrays.get("reflectivity"), frame_id=str(msg.header.frame_id), height=height, width=width)


def _numpy_arrays(msg: Any, records: np.ndarray, dtype: np.dtype[Any], names: set[str]) -> dict[str, Any]:
    """The Sweep's arrays by numpy (any layout; the reference the C path must equal)."""
    height, width = int(msg.height), int(msg.width)
    arr = records.view(dtype).reshape(width * height)
    # No return: all-zero or non-finite xyz. Elementwise on the three fields (row reductions
    # over a strided (N, 3) view cost several times more); the sum is NaN/inf when any is.
    norm1 = np.abs(arr["x"].astype(np.float32)) + np.abs(arr["y"]) + np.abs(arr["z"])
    valid = np.isfinite(norm1) & (norm1 > 0)
    # compact the raw records once (a plain byte copy; take() beats boolean indexing of rows),
    # then read contiguous fields
    kept = records.take(np.flatnonzero(valid), axis=0).view(dtype).reshape(-1)
    points = np.empty((kept.shape[0], 3), dtype=np.float32)
    for k, name in enumerate("xyz"):
        points[:, k] = kept[name]
    organised = height > 1
    out: dict[str, Any] = {"points": points, "kept": kept}
    if "ring" in names or organised:
        out["ring"] = kept["ring"].astype(np.uint16) if "ring" in names else (
            np.repeat(np.arange(height, dtype=np.uint16), width)[valid])
    if organised:
        out["column"] = np.tile(np.arange(width, dtype=np.uint32), height)[valid]
    for name in ("intensity", "reflectivity"):
        if name in names:
            out[name] = kept[name].astype(np.float32)
    return out


def _gathered(msg: Any, data: np.ndarray, names: set[str]) -> dict[str, Any] | None:
    """The Sweep's arrays in one pass of io/_cloud.c (equal to `_numpy_arrays`'), for little-endian
    clouds with float32 x/y/z and the usual fields; None otherwise, or without the C module."""
    plan, gather = _gather_plan(msg, names), _gather_c
    if plan is None or gather is None:
        return None
    height, width = int(msg.height), int(msg.width)
    n = height * width
    by = {f.name: f for f in msg.fields}
    points = np.empty((n, 3), np.float32)
    outs: dict[str, np.ndarray] = {key: np.empty(n, out_type) for key, _kind, _field, out_type in plan}
    columns = tuple((kind, int(by[field].offset) if field else 0, int(by[field].datatype) if field else 0, outs[key])
                    for key, kind, field, _t in plan)
    kept = gather(data, (height, width, int(msg.point_step), int(msg.row_step) or width * int(msg.point_step)),
                         tuple(int(by[c].offset) for c in "xyz"), points, columns)
    points.resize((kept, 3), refcheck=False)  # in place (the unused tail is given back)
    for arr in outs.values():
        arr.resize(kept, refcheck=False)
    return {"points": points, **outs}


def _gather_plan(msg: Any, names: set[str]) -> list[tuple[str, int, str, type]] | None:
    """(output, kind, field, dtype) of each array besides the points, or None when the C path
    does not apply (kinds as io/_cloud.c numbers them)."""
    if _gather_c is None or bool(msg.is_bigendian) or sys.byteorder != "little":
        return None
    by = {f.name: f for f in msg.fields}
    used = [n for n in ("x", "y", "z", "ring", "intensity", "reflectivity", "t", "time", "timestamp") if n in by]
    if any(by[n].count != 1 for n in used) or any(by[c].datatype != 7 for c in "xyz") or "timestamp" in by \
            or ("ring" in by and by["ring"].datatype not in (2, 4)) or int(msg.height) > 65536:
        return None
    plan: list[tuple[str, int, str, type]] = []
    if "ring" in by:
        plan.append(("ring", _UINT16, "ring", np.uint16))
    elif int(msg.height) > 1:
        plan.append(("ring", _ROW, "", np.uint16))
    if int(msg.height) > 1:
        plan.append(("column", _COLUMN, "", np.uint32))
    plan += [(name, _FLOAT32, name, np.float32) for name in ("intensity", "reflectivity") if name in by]
    if "t" in by:
        plan.append(("time", _NS_TO_S, "t", np.float32))
    elif "time" in by:
        plan.append(("time", _FLOAT32, "time", np.float32))
    return plan


def _layout(msg: Any) -> tuple[np.ndarray, np.dtype[Any]]:
    """The cloud's bytes and the structured dtype that reads a point; CloudFormatError when the
    sizes do not add up or the fields do not fit."""
    height, width, step = int(msg.height), int(msg.width), int(msg.point_step)
    data = np.asarray(msg.data, dtype=np.uint8)
    row_step = int(msg.row_step) or width * step
    if step <= 0 or row_step < width * step or data.size < max(height - 1, 0) * row_step + width * step:
        raise CloudFormatError(f"PointCloud2 data has {data.size} bytes, expected {height} rows x {width} points"
                               f" x {step} bytes (row_step {row_step})")
    key = tuple((f.name, int(f.offset), int(f.datatype), int(f.count)) for f in msg.fields)
    try:
        dtype = _cached_dtype(key, step, bool(msg.is_bigendian))
    except ValueError as err:  # a field beyond point_step, overlapping names...
        raise CloudFormatError(f"PointCloud2 fields do not fit point_step {step}: {err}") from err
    return data, dtype


def _records(msg: Any, data: np.ndarray) -> np.ndarray:
    """The cloud's points as raw records (n, point_step) bytes, row padding dropped."""
    height, width, step = int(msg.height), int(msg.width), int(msg.point_step)
    n = width * height
    row_step = int(msg.row_step) or width * step
    if height > 1 and row_step != width * step:  # padded rows: drop the padding
        rows = np.lib.stride_tricks.as_strided(data, (height, width * step), (row_step, 1))
        return np.ascontiguousarray(rows).reshape(n, step)
    return data[: n * step].reshape(n, step)


def _time_of(arrays: dict[str, Any], names: set[str], stamp: float) -> np.ndarray | None:
    if "kept" in arrays:
        return _point_time(arrays["kept"], names, stamp)
    return arrays.get("time")


def _point_time(arr: np.ndarray, names: set[str], stamp: float) -> np.ndarray | None:
    if "t" in names:  # Ouster: u32 ns since the sweep start
        return arr["t"].astype(np.float32) * np.float32(1e-9)
    if "time" in names:  # Velodyne: f32 s relative to the header stamp
        return np.ascontiguousarray(arr["time"], dtype=np.float32)
    if "timestamp" in names:  # f64 s, absolute (Hesai, Livox) or relative
        ts = arr["timestamp"].astype(np.float64)
        if ts.size and np.nanmax(ts) > 1e6:  # absolute epoch or sensor-clock seconds
            ts = ts - stamp
        return ts.astype(np.float32)
    return None


def cloud_fields(msg: Any) -> list[str]:
    return [f.name for f in msg.fields]
