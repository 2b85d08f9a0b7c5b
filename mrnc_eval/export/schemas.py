"""The Foxglove message schemas we write, loaded from the official JSON Schema files
(export/foxglove_schemas/, copied unchanged from foxglove/foxglove-sdk; source and commit in
SOURCE.md there), and the JSON Schema of our own plottable scalars.

Schema names `foxglove.<Name>`, times as {sec, nsec}, binary data as base64 strings, enums as
integers. With schema encoding "jsonschema" and message encoding "json", Foxglove and its open
fork Lichtblick open them without extensions. The official schemas require every field (a
SceneEntity lists arrows, cubes, ... even when empty); the builders in mcap_file fill them."""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from typing import Any

Schema = dict[str, Any]

TIME: Schema = {"type": "object", "title": "time", "properties": {
    "sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}},
    "required": ["sec", "nsec"]}


@cache
def official(name: str) -> Schema:
    """The published schema foxglove.<name> (e.g. "SceneUpdate")."""
    text = resources.files("mrnc_eval.export").joinpath("foxglove_schemas", f"{name}.json").read_text("utf-8")
    schema: Schema = json.loads(text)
    return schema


def _object(title: str, description: str, properties: dict[str, Schema], required: list[str] | None = None) -> Schema:
    return {"title": title, "description": description, "type": "object", "properties": properties,
            "required": list(properties) if required is None else required}


POSE_IN_FRAME = official("PoseInFrame")
POSES_IN_FRAME = official("PosesInFrame")
FRAME_TRANSFORM = official("FrameTransform")
POINT_CLOUD = official("PointCloud")
SCENE_UPDATE = official("SceneUpdate")
LOG = official("Log")

FLOAT32 = 7  # foxglove.NumericType
LINE_STRIP, LINE_LIST = 0, 2  # foxglove.LineType
DEBUG, INFO, WARNING, ERROR = 1, 2, 3, 4  # foxglove.LogLevel

FOXGLOVE: dict[str, Schema] = {s["title"]: s for s in (
    POSE_IN_FRAME, POSES_IN_FRAME, FRAME_TRANSFORM, POINT_CLOUD, SCENE_UPDATE, LOG)}


def scalars(title: str, fields: dict[str, str]) -> Schema:
    """A plain JSON message of named numbers (plottable in Foxglove's Plot panel and PlotJuggler);
    `fields` maps each name to its description (with the unit)."""
    props: dict[str, Schema] = {"timestamp": TIME}
    props.update({name: {"type": "number", "description": text} for name, text in fields.items()})
    # only the stamp is required: a value that is not a finite number (NaN) is left out, as JSON has no NaN
    return _object(title, "Plottable values of one sample; the unit is in each field's description", props,
                   required=["timestamp"])
