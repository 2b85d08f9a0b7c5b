"""The pose of one TF frame in another over time, composed through intermediate frames.

Like tf2's lookup: edges come from /tf (dynamic, stamped) and /tf_static (constant); the
chain between the two frames may run against an edge's direction (then it is inverted).
Each dynamic edge on the chain is interpolated (linear position, slerp rotation) at the
stamps of the fastest dynamic edge on it, inside the time all of them cover (tf2 refuses
to extrapolate, and so do we). A missing link is an error that names both sides.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np

from mrnc_eval.data import Trajectory
from mrnc_eval.errors import InputError
from mrnc_eval.geometry import lie
from mrnc_eval.geometry.interpolate import interpolate_at, sorted_unique

Edge = tuple[str, str]  # (parent, child)


@dataclass(frozen=True)
class EdgeSamples:
    """One TF edge: the pose of `child` in `parent` at each stamp (one pose if static)."""

    parent: str
    child: str
    traj: Trajectory  # sorted, repeated stamps dropped
    static: bool

    @property
    def rate_hz(self) -> float:
        span = float(self.traj.stamps[-1] - self.traj.stamps[0])
        return (len(self.traj) - 1) / span if span > 0 else 0.0


def _frame(name: str) -> str:
    return name.lstrip("/")


def edges_from_messages(dynamic: Iterable[Any], static: Iterable[Any]) -> dict[Edge, EdgeSamples]:
    """TF edges from TFMessage objects of the dynamic and the static topic; a static edge
    keeps its last transform."""
    raw: dict[tuple[Edge, bool], list[tuple[float, float, float, float, float, float, float, float]]] = {}
    for is_static, messages in ((False, dynamic), (True, static)):
        for msg in messages:
            for tr in msg.transforms:
                st, v, r = tr.header.stamp, tr.transform.translation, tr.transform.rotation
                key = ((_frame(tr.header.frame_id), _frame(tr.child_frame_id)), is_static)
                raw.setdefault(key, []).append((float(st.sec) + float(st.nanosec) * 1e-9, v.x, v.y, v.z,
                                                r.x, r.y, r.z, r.w))
    edges: dict[Edge, EdgeSamples] = {}
    for (edge, is_static), rows in raw.items():
        a = np.asarray(rows[-1:] if is_static else rows, dtype=float)
        traj = sorted_unique(Trajectory(a[:, 0], a[:, 1:4], a[:, 4:8], name=f"{edge[0]}->{edge[1]}"))
        if edge not in edges or is_static:  # an edge published on both topics counts as static
            edges[edge] = EdgeSamples(edge[0], edge[1], traj, is_static)
    return edges


def _component(adjacent: dict[str, set[str]], start: str) -> set[str]:
    seen, todo = {start}, [start]
    while todo:
        for nxt in adjacent.get(todo.pop(), ()):
            if nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    return seen


def frame_path(edges: Iterable[Edge], parent: str, child: str, *, where: str | Path) -> list[str]:
    """Frames from `parent` to `child` (breadth first: the fewest edges), or an InputError
    naming what is missing."""
    adjacent: dict[str, set[str]] = {}
    for a, b in edges:
        adjacent.setdefault(a, set()).add(b)
        adjacent.setdefault(b, set()).add(a)
    for frame in (parent, child):
        if frame not in adjacent:
            known = ", ".join(sorted(adjacent)) or "none"
            raise InputError(where, f"frame {frame!r} is not in the TF tree (frames: {known})", topic="/tf")
    came_from: dict[str, str] = {parent: parent}
    queue = [parent]
    for frame in queue:  # the list grows while it is walked: breadth first
        if frame == child:
            break
        for nxt in sorted(adjacent[frame]):
            if nxt not in came_from:
                came_from[nxt] = frame
                queue.append(nxt)
    if child not in came_from:
        near, far = sorted(_component(adjacent, parent)), sorted(_component(adjacent, child))
        raise InputError(where, f"no TF chain from {parent!r} to {child!r}: {parent!r} connects only "
                                f"{', '.join(near)} and {child!r} only {', '.join(far)}; the transform linking "
                                "these two trees is missing", topic="/tf")
    path = [child]
    while path[-1] != parent:
        path.append(came_from[path[-1]])
    return path[::-1]


def chain_trajectory(edges: dict[Edge, EdgeSamples], parent: str, child: str, *, where: str | Path,
                     name: str = "") -> Trajectory:
    """Pose of `child` in `parent` at the stamps of the fastest dynamic edge between them."""
    frames = frame_path(edges, parent, child, where=where)
    hops = [(edges[(a, b)], False) if (a, b) in edges else (edges[(b, a)], True) for a, b in pairwise(frames)]
    dynamic = [e for e, _ in hops if not e.static]
    if not dynamic:
        raise InputError(where, f"only static transforms link {parent!r} and {child!r}: no trajectory", topic="/tf")
    if len(hops) == 1 and not hops[0][1]:  # one edge, as published
        e = hops[0][0]
        return Trajectory(e.traj.stamps, e.traj.positions, e.traj.quat_xyzw, name=name, frame_id=parent,
                          child_frame_id=child)
    fastest = max(dynamic, key=lambda e: e.rate_hz)
    start = max(e.traj.stamps[0] for e in dynamic)
    end = min(e.traj.stamps[-1] for e in dynamic)
    stamps = fastest.traj.stamps[(fastest.traj.stamps >= start) & (fastest.traj.stamps <= end)]
    if stamps.size == 0:
        spans = "; ".join(f"{e.parent}->{e.child} {e.traj.stamps[0]:.3f}..{e.traj.stamps[-1]:.3f} s" for e in dynamic)
        raise InputError(where, f"the dynamic transforms from {parent!r} to {child!r} never overlap in time "
                                f"({spans})", topic="/tf")
    total = np.tile(np.eye(4), (stamps.size, 1, 1))
    for edge, inverted in hops:
        if edge.static:
            t = np.broadcast_to(lie.poses(edge.traj)[-1], (stamps.size, 4, 4))
        else:
            t = lie.poses(interpolate_at(edge.traj, stamps, max_gap=np.inf)[0])
        total = np.matmul(total, lie.inverse(t) if inverted else t)
    return Trajectory(stamps.copy(), total[:, :3, 3].copy(), lie.matrix_to_quat_xyzw(total[:, :3, :3]), name=name,
                      frame_id=parent, child_frame_id=child)
