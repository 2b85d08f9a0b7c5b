"""JSON Schema definitions of the Foxglove message schemas we write, and of our plottable scalars.

Written from the published field tables of the Foxglove schemas (docs.foxglove.dev, "Message
schemas"): schema names `foxglove.<Name>`, times as {sec, nsec}, binary data as a base64 string
with `"contentEncoding": "base64"`, enums as integers. With schema encoding "jsonschema" and
message encoding "json", Foxglove and its open fork Lichtblick open them without extensions.
Only the fields we fill are required; the viewers read the rest as absent."""

from __future__ import annotations

from typing import Any

Schema = dict[str, Any]

NUMBER: Schema = {"type": "number"}
STRING: Schema = {"type": "string"}
UINT: Schema = {"type": "integer", "minimum": 0}

TIME: Schema = {"type": "object", "title": "time", "properties": {
    "sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}},
    "required": ["sec", "nsec"]}
DURATION: Schema = {"type": "object", "title": "duration", "properties": {
    "sec": {"type": "integer"}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}},
    "required": ["sec", "nsec"]}


def _object(title: str, description: str, properties: dict[str, Schema], required: list[str] | None = None) -> Schema:
    return {"title": title, "description": description, "type": "object", "properties": properties,
            "required": list(properties) if required is None else required}


VECTOR3 = _object("foxglove.Vector3", "A vector in 3D space", {"x": NUMBER, "y": NUMBER, "z": NUMBER})
POINT3 = _object("foxglove.Point3", "A point in 3D space", {"x": NUMBER, "y": NUMBER, "z": NUMBER})
QUATERNION = _object("foxglove.Quaternion", "A quaternion (x, y, z, w)",
                     {"x": NUMBER, "y": NUMBER, "z": NUMBER, "w": NUMBER})
POSE = _object("foxglove.Pose", "A position and orientation in 3D space",
               {"position": VECTOR3, "orientation": QUATERNION})
COLOR = _object("foxglove.Color", "A color in RGBA format (0..1)", {"r": NUMBER, "g": NUMBER, "b": NUMBER, "a": NUMBER})

POSE_IN_FRAME = _object("foxglove.PoseInFrame", "A timestamped pose in a reference frame",
                        {"timestamp": TIME, "frame_id": STRING, "pose": POSE})
POSES_IN_FRAME = _object("foxglove.PosesInFrame", "An array of timestamped poses in a reference frame",
                         {"timestamp": TIME, "frame_id": STRING, "poses": {"type": "array", "items": POSE}})
FRAME_TRANSFORM = _object("foxglove.FrameTransform", "A transform between two reference frames",
                          {"timestamp": TIME, "parent_frame_id": STRING, "child_frame_id": STRING,
                           "translation": VECTOR3, "rotation": QUATERNION})

NUMERIC_TYPE: Schema = {"title": "foxglove.NumericType", "description": "Numeric type", "oneOf": [
    {"title": name, "const": value} for value, name in enumerate(
        ("UNKNOWN", "UINT8", "INT8", "UINT16", "INT16", "UINT32", "INT32", "FLOAT32", "FLOAT64"))]}
FLOAT32 = 7  # NumericType value
PACKED_ELEMENT_FIELD = _object("foxglove.PackedElementField", "A field of each element of a packed byte array",
                               {"name": STRING, "offset": UINT, "type": NUMERIC_TYPE})
POINT_CLOUD = _object("foxglove.PointCloud", "A collection of N-dimensional points",
                      {"timestamp": TIME, "frame_id": STRING, "pose": POSE, "point_stride": UINT,
                       "fields": {"type": "array", "items": PACKED_ELEMENT_FIELD},
                       "data": {"type": "string", "contentEncoding": "base64"}})

LINE_STRIP, LINE_LIST = 0, 2  # LineType values
LINE_PRIMITIVE = _object("foxglove.LinePrimitive", "A series of points connected by lines", {
    "type": {"title": "foxglove.LineType", "oneOf": [{"title": "LINE_STRIP", "const": 0},
                                                     {"title": "LINE_LOOP", "const": 1},
                                                     {"title": "LINE_LIST", "const": 2}]},
    "pose": POSE, "thickness": NUMBER, "scale_invariant": {"type": "boolean"},
    "points": {"type": "array", "items": POINT3}, "color": COLOR, "colors": {"type": "array", "items": COLOR},
    "indices": {"type": "array", "items": UINT}}, required=["type", "pose", "thickness", "scale_invariant", "points"])
KEY_VALUE = _object("foxglove.KeyValuePair", "A key with its value", {"key": STRING, "value": STRING})
SCENE_ENTITY = _object("foxglove.SceneEntity", "A visual element in a 3D scene", {
    "timestamp": TIME, "frame_id": STRING, "id": STRING, "lifetime": DURATION, "frame_locked": {"type": "boolean"},
    "metadata": {"type": "array", "items": KEY_VALUE}, "lines": {"type": "array", "items": LINE_PRIMITIVE}},
    required=["timestamp", "frame_id", "id", "lifetime", "frame_locked"])
SCENE_ENTITY_DELETION = _object("foxglove.SceneEntityDeletion", "A command to remove scene entities", {
    "timestamp": TIME, "type": {"title": "foxglove.SceneEntityDeletionType",
                                "oneOf": [{"title": "MATCHING_ID", "const": 0}, {"title": "ALL", "const": 1}]},
    "id": STRING})
SCENE_UPDATE = _object("foxglove.SceneUpdate", "An update to the entities displayed in a 3D scene", {
    "deletions": {"type": "array", "items": SCENE_ENTITY_DELETION},
    "entities": {"type": "array", "items": SCENE_ENTITY}})

DEBUG, INFO, WARNING, ERROR = 1, 2, 3, 4  # LogLevel values
LOG = _object("foxglove.Log", "A log message", {
    "timestamp": TIME, "level": {"title": "foxglove.LogLevel", "oneOf": [
        {"title": name, "const": value} for value, name in enumerate(
            ("UNKNOWN", "DEBUG", "INFO", "WARNING", "ERROR", "FATAL"))]},
    "message": STRING, "name": STRING, "file": STRING, "line": UINT})

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
