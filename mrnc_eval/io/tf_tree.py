"""The TF tree of an open log: its static transforms, a static pose looked up through them,
and a frame's trajectory through /tf and /tf_static (composed in io/tf_chain.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mrnc_eval.data import Trajectory
from mrnc_eval.errors import InputError
from mrnc_eval.io.series import SeriesReader
from mrnc_eval.io.validate import bad_quaternions, non_finite

_TF_TYPES = ("tf2_msgs/msg/TFMessage",)
StaticTransforms = dict[tuple[str, str], np.ndarray]  # (parent, child) -> 4x4 pose of child in parent


def _quat_to_matrix(q: np.ndarray) -> np.ndarray:
    from mrnc_eval.geometry import rotation

    matrix: np.ndarray = rotation.quat_to_matrix(q)
    return matrix


def static_transforms(series: SeriesReader, topic: str | None) -> StaticTransforms:
    """Every transform on the /tf_static topic (none without one); a non-finite or non-unit one is an error."""
    out: StaticTransforms = {}
    if topic is None:
        return out
    tolerance = series.cfg.validation.quat_norm_tolerance
    for m in series.src.messages(topic, _TF_TYPES):
        for tr in m.transforms:
            v, r = tr.transform.translation, tr.transform.rotation
            q = np.array([r.x, r.y, r.z, r.w], float)
            xyz = np.array([[v.x, v.y, v.z]], float)
            if bad_quaternions(q, tolerance)[0] or non_finite(xyz)[0]:
                raise InputError(series.src.path, f"static transform {tr.header.frame_id} -> {tr.child_frame_id}: "
                                 f"translation {v.x, v.y, v.z} / rotation {tuple(q)} is not finite or not a "
                                 "unit quaternion", topic=topic)
            mat = np.eye(4)
            mat[:3, :3] = _quat_to_matrix(q)
            mat[:3, 3] = (v.x, v.y, v.z)
            out[(tr.header.frame_id.lstrip("/"), tr.child_frame_id.lstrip("/"))] = mat
    return out


def static_pose(transforms: StaticTransforms, parent: str, child: str, *, where: Path) -> np.ndarray:
    """Pose of `child` in `parent` (4x4), composed along the static tree (edges walked either way)."""
    edges: dict[str, list[tuple[str, np.ndarray]]] = {}
    for (a, b), mat in transforms.items():
        edges.setdefault(a, []).append((b, mat))
        edges.setdefault(b, []).append((a, np.linalg.inv(mat)))
    frontier, seen = [(parent, np.eye(4))], {parent}
    while frontier:
        frame, acc = frontier.pop()
        if frame == child:
            return acc
        for nxt, mat in edges.get(frame, []):
            if nxt not in seen:
                seen.add(nxt)
                frontier.append((nxt, acc @ mat))
    raise InputError(where, f"no static transform from {parent!r} to {child!r}", topic="/tf_static")


def tf_trajectory(series: SeriesReader, spec: str, static_topic: str | None) -> Trajectory:
    """`child` in `parent` through the TF tree (/tf and /tf_static), as tf2 looks it up;
    `spec` is "/tf:parent.child" (or "/tf_static:parent.child")."""
    from mrnc_eval.io.tf_chain import chain_trajectory, edges_from_messages

    src = series.src
    tf_topic, _, frames = spec.partition(":")
    parent, _, child = frames.partition(".")
    if not parent or not child:
        raise InputError(src.path, f"TF spec {spec!r} must be /tf:parent.child")
    static = src.messages(static_topic, _TF_TYPES) if static_topic and static_topic != tf_topic else ()
    edges = edges_from_messages(src.messages(tf_topic, _TF_TYPES), static)
    traj = chain_trajectory(edges, parent, child, where=src.path, name=spec)
    t_a, p_a, q_a = series.valid_poses(tf_topic, traj.stamps, traj.positions, traj.quat_xyzw)
    return Trajectory(t_a, p_a, q_a, name=spec, frame_id=parent, child_frame_id=child)
