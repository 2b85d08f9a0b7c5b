"""PointCloud2 decoding by field name and datatype (never by fixed offsets).

Supports the Ouster layout (`t` u32 ns since sweep start, `ring` u8/u16, `range`,
`reflectivity`), the Velodyne layout (`time` f32 s relative), and `timestamp` f64
(absolute or relative seconds). No-return points (all-zero or non-finite xyz) are removed
together with their per-point times; point time is normalised to seconds since the
header stamp (the sweep start).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from mrnc_eval.data import Sweep

# sensor_msgs/PointField datatypes -> numpy
_DTYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


class CloudFormatError(ValueError):
    """The cloud's layout cannot be decoded (missing x/y/z, bad sizes)."""


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
    records, dtype = _records(msg)
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
    ring = kept["ring"].astype(np.uint16) if "ring" in names else (
        np.repeat(np.arange(height, dtype=np.uint16), width)[valid] if organised else None)
    column = np.tile(np.arange(width, dtype=np.uint32), height)[valid] if organised else None
    intensity = kept["intensity"].astype(np.float32) if "intensity" in names else None
    reflectivity = kept["reflectivity"].astype(np.float32) if "reflectivity" in names else None
    return Sweep(stamp=stamp, points=points, point_time=_point_time(kept, names, stamp), ring=ring, column=column,
                 intensity=intensity, reflectivity=reflectivity, frame_id=str(msg.header.frame_id), height=height,
                 width=width)


def _records(msg: Any) -> tuple[np.ndarray, np.dtype[Any]]:
    """The cloud's points as raw records (n, point_step) bytes, row padding dropped, and the
    structured dtype that reads their fields; CloudFormatError when the sizes do not add up."""
    height, width, step = int(msg.height), int(msg.width), int(msg.point_step)
    n = width * height
    data = np.asarray(msg.data, dtype=np.uint8)
    row_step = int(msg.row_step) or width * step
    if step <= 0 or row_step < width * step or data.size < max(height - 1, 0) * row_step + width * step:
        raise CloudFormatError(f"PointCloud2 data has {data.size} bytes, expected {height} rows x {width} points"
                               f" x {step} bytes (row_step {row_step})")
    try:
        dtype = structured_dtype(msg.fields, step, bool(msg.is_bigendian))
    except ValueError as err:  # a field beyond point_step, overlapping names...
        raise CloudFormatError(f"PointCloud2 fields do not fit point_step {step}: {err}") from err
    if height > 1 and row_step != width * step:  # padded rows: drop the padding
        rows = np.lib.stride_tricks.as_strided(data, (height, width * step), (row_step, 1))
        records = np.ascontiguousarray(rows).reshape(n, step)
    else:
        records = data[: n * step].reshape(n, step)
    return records, dtype


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
