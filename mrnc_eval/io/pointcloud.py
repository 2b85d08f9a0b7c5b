"""PointCloud2 decoding by field name and datatype (never by fixed offsets).

Supports the Ouster layout (`t` u32 ns since sweep start, `ring` u8/u16, `range`,
`reflectivity`), the Velodyne layout (`time` f32 s relative), and `timestamp` f64
(absolute or relative seconds). No-return points (all-zero or non-finite xyz) are removed
together with their per-point times; point time is normalised to seconds since the
header stamp (the sweep start).
"""

from __future__ import annotations

import numpy as np

from mrnc_eval.data import Sweep

# sensor_msgs/PointField datatypes -> numpy
_DTYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


class CloudFormatError(ValueError):
    """The cloud's layout cannot be decoded (missing x/y/z, bad sizes)."""


def structured_dtype(fields, point_step: int, big_endian: bool) -> np.dtype:
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


def decode_cloud(msg, stamp: float) -> Sweep:
    """Decode a sensor_msgs/PointCloud2 message into a Sweep (no-return points removed)."""
    names = {f.name for f in msg.fields}
    missing = {"x", "y", "z"} - names
    if missing:
        raise CloudFormatError(f"PointCloud2 has no {'/'.join(sorted(missing))} field(s) (fields: {sorted(names)})")
    n = int(msg.width) * int(msg.height)
    data = np.asarray(msg.data, dtype=np.uint8)
    if msg.point_step <= 0 or data.size < n * msg.point_step:
        raise CloudFormatError(
            f"PointCloud2 data has {data.size} bytes, expected {n} points x {msg.point_step} bytes"
        )
    dtype = structured_dtype(msg.fields, int(msg.point_step), bool(msg.is_bigendian))
    row_step = int(msg.row_step) or int(msg.width) * int(msg.point_step)
    if msg.height > 1 and row_step != msg.width * msg.point_step:
        rows = [np.frombuffer(data[r * row_step : r * row_step + msg.width * msg.point_step], dtype=dtype)
                for r in range(msg.height)]
        arr = np.concatenate(rows)
    else:
        arr = np.frombuffer(data[: n * msg.point_step], dtype=dtype)

    xyz = np.stack([arr["x"], arr["y"], arr["z"]], axis=1).astype(np.float32, copy=False)
    valid = np.isfinite(xyz).all(axis=1) & (np.abs(xyz).sum(axis=1) > 0.0)

    point_time = _point_time(arr, names, stamp)
    index = np.arange(n, dtype=np.int64)
    width = max(int(msg.width), 1)
    ring = arr["ring"].astype(np.uint16) if "ring" in names else (
        (index // width).astype(np.uint16) if msg.height > 1 else None)
    column = (index % width).astype(np.uint32) if msg.height > 1 else None
    intensity = arr["intensity"].astype(np.float32) if "intensity" in names else None
    reflectivity = arr["reflectivity"].astype(np.float32) if "reflectivity" in names else None

    def keep(a):
        return None if a is None else np.ascontiguousarray(a[valid])

    return Sweep(
        stamp=stamp,
        points=np.ascontiguousarray(xyz[valid]),
        point_time=keep(point_time),
        ring=keep(ring),
        column=keep(column),
        intensity=keep(intensity),
        reflectivity=keep(reflectivity),
        frame_id=str(msg.header.frame_id),
        height=int(msg.height),
        width=int(msg.width),
    )


def _point_time(arr: np.ndarray, names: set[str], stamp: float) -> np.ndarray | None:
    if "t" in names:  # Ouster: u32 ns since the sweep start
        return (arr["t"].astype(np.float64) * 1e-9).astype(np.float32)
    if "time" in names:  # Velodyne: f32 s relative to the header stamp
        return arr["time"].astype(np.float32)
    if "timestamp" in names:  # f64 s, absolute (Hesai, Livox) or relative
        ts = arr["timestamp"].astype(np.float64)
        if ts.size and np.nanmax(ts) > 1e6:  # absolute epoch or sensor-clock seconds
            ts = ts - stamp
        return ts.astype(np.float32)
    return None


def cloud_fields(msg) -> list[str]:
    return [f.name for f in msg.fields]
