"""An MCAP file of JSON messages with JSON Schema schemas (what Foxglove and Lichtblick open
without extensions), plus the small builders of the Foxglove message bodies we write.

Every message is stamped twice with the same header stamp: in its body (`timestamp`) and as
the MCAP log/publish time, so the viewer's timeline is the original log's."""

from __future__ import annotations

import base64
import json
import math
from collections import Counter
from typing import IO, Any

import numpy as np

from mrnc_eval import __version__
from mrnc_eval.export import schemas
from mrnc_eval.export.schemas import Schema


def stamp_ns(t_s: float) -> int:
    return int(round(t_s * 1e9))


def time_of(t_ns: int) -> dict[str, int]:
    sec, nsec = divmod(max(int(t_ns), 0), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def _finite_or_none(value: Any) -> Any:
    """JSON has no NaN/inf: such values are dropped by `clean` (plots show a gap)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def clean(body: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in ((k, _finite_or_none(v)) for k, v in body.items()) if v is not None}


def pose(xyz: Any, quat_xyzw: Any = (0.0, 0.0, 0.0, 1.0)) -> dict[str, Any]:
    x, y, z = (float(v) for v in xyz)
    qx, qy, qz, qw = (float(v) for v in quat_xyzw)
    return {"position": {"x": x, "y": y, "z": z}, "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}}


def point(xyz: Any) -> dict[str, float]:
    x, y, z = (float(v) for v in xyz)
    return {"x": x, "y": y, "z": z}


def color(r: float, g: float, b: float, a: float = 1.0) -> dict[str, float]:
    return {"r": r, "g": g, "b": b, "a": a}


def point_cloud(t_ns: int, frame_id: str, xyz: np.ndarray) -> dict[str, Any]:
    """foxglove.PointCloud of float32 x, y, z (12-byte stride, little endian)."""
    data = np.ascontiguousarray(xyz, dtype="<f4").tobytes()
    fields = [{"name": n, "offset": 4 * k, "type": schemas.FLOAT32} for k, n in enumerate("xyz")]
    return {"timestamp": time_of(t_ns), "frame_id": frame_id, "pose": pose((0, 0, 0)), "point_stride": 12,
            "fields": fields, "data": base64.b64encode(data).decode("ascii")}


def line_entity(t_ns: int, frame_id: str, entity_id: str, lines: list[dict[str, Any]]) -> dict[str, Any]:
    """A foxglove.SceneEntity of lines; the other primitive lists are empty (the schema requires them)."""
    return {"timestamp": time_of(t_ns), "frame_id": frame_id, "id": entity_id, "lifetime": {"sec": 0, "nsec": 0},
            "frame_locked": False, "metadata": [], "arrows": [], "cubes": [], "spheres": [], "cylinders": [],
            "lines": lines, "triangles": [], "texts": [], "models": []}


def line(kind: int, xyz: np.ndarray, rgba: dict[str, float], thickness_px: float = 2.0) -> dict[str, Any]:
    return {"type": kind, "pose": pose((0, 0, 0)), "thickness": thickness_px, "scale_invariant": True,
            "points": [point(p) for p in xyz], "color": rgba, "colors": [], "indices": []}


class JsonMcap:
    """Registers each schema and topic once; counts messages per topic."""

    def __init__(self, stream: IO[bytes]) -> None:
        from mcap.writer import CompressionType, Writer

        self.writer = Writer(stream, compression=CompressionType.ZSTD)
        self.writer.start(profile="", library=f"mrnc-eval {__version__}")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self.counts: Counter[str] = Counter()

    def channel(self, topic: str, schema: Schema) -> int:
        if topic not in self._channels:
            name = schema["title"]
            if name not in self._schemas:
                self._schemas[name] = self.writer.register_schema(
                    name, "jsonschema", json.dumps(schema, separators=(",", ":")).encode())
            self._channels[topic] = self.writer.register_channel(topic, "json", self._schemas[name])
        return self._channels[topic]

    def write(self, topic: str, schema: Schema, t_ns: int, body: dict[str, Any]) -> None:
        channel = self.channel(topic, schema)
        data = json.dumps(body, separators=(",", ":"), allow_nan=False).encode()
        self.writer.add_message(channel, log_time=t_ns, data=data, publish_time=t_ns, sequence=self.counts[topic])
        self.counts[topic] += 1

    def finish(self) -> None:
        self.writer.finish()  # type: ignore[no-untyped-call, unused-ignore]  # mcap: unannotated
