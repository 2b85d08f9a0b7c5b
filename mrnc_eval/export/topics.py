"""What a result becomes in the exported MCAP: one function per kind of content.

Topics live under `/eval/` so they never collide with the original sensor topics that
`--with-log` copies into the same file. Frames make one tree, rooted in the ground truth's frame
(the frame its source declares, e.g. the log's `map`; the viewer's fixed frame):

    map (ground truth, planned and driven paths, the log's own /ground_truth and /plan)
     └─ lio/map          the SLAM estimate's frame, namespaced by method; /eval/tf: the 4-DoF
         │               (yaw + translation) alignment of the estimate to the ground truth
         │               (identity without one)
         └─ base_link    the SLAM pose at each stamp (/eval/tf), so the log's /tf_static chain
             └─ ...      (base_link -> os_sensor, imu, gnss) places its clouds, IMU and GNSS

     └─ odom         the wheel odometry's frame, as SLAM systems publish it (REP 105):
                     odom in lio/map = P(t) O(t)^-1 at each SLAM stamp, so the log's
                     /wheel_odom draws where the SLAM puts the robot at that moment

A second SLAM result (another method) hangs its poses on `<method>/base_link`, so no frame has
two parents."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from mrnc_eval.data import Trajectory
from mrnc_eval.errors import InputError
from mrnc_eval.export import schemas as S
from mrnc_eval.export.mcap_file import (
    JsonMcap,
    clean,
    color,
    line,
    line_entity,
    point_cloud,
    pose,
    stamp_ns,
    time_of,
)
from mrnc_eval.results import Event, RunResult
from mrnc_eval.schema import control as control_keys
from mrnc_eval.schema import slam as slam_keys

ROOT = "/eval"
MAP_POINTS_MAX = 100_000  # a viewer opens 100k points (1.2 MB of float32) instantly
KEYFRAME_UPDATES_MAX = 200  # scene updates of the growing keyframe graph (each holds the whole graph so far)
EVENT_LEVEL = {"degeneracy": S.WARNING, "warning": S.WARNING, "safety_stop": S.ERROR, "slip": S.WARNING,
               "loop_closure": S.INFO, "gps": S.INFO}
TRACKING_FIELDS = {
    "v_ref_left_mps": "left wheel reference speed, m/s", "v_ref_right_mps": "right wheel reference speed, m/s",
    "v_left_mps": "left wheel measured speed, m/s", "v_right_mps": "right wheel measured speed, m/s",
    "error_left_mps": "left tracking error e = v - v_ref, m/s", "error_right_mps": "right tracking error, m/s",
    "funnel_upper_mps": "funnel bound +o(t), m/s", "funnel_lower_mps": "funnel bound -o(t), m/s",
    "u_left_rpm": "left pump command, RPM", "u_right_rpm": "right pump command, RPM",
    "saturated_left": "1 while the left command is at its limit", "saturated_right": "1 while the right is",
    "cross_track_m": "cross-track error to the planned path, m", "safety_stops": "safety stops so far (count)"}


def _poses(traj: Trajectory) -> list[dict[str, Any]]:
    return [pose(p, q) for p, q in zip(traj.positions, traj.quat_xyzw, strict=True)]


def write_trajectory(out: JsonMcap, topic: str, traj: Trajectory, frame_id: str) -> None:
    """One PoseInFrame per pose at its stamp, and the whole path once at the first stamp."""
    for t, p, q in zip(traj.stamps, traj.positions, traj.quat_xyzw, strict=True):
        t_ns = stamp_ns(float(t))
        out.write(f"{topic}/pose", S.POSE_IN_FRAME, t_ns, {"timestamp": time_of(t_ns), "frame_id": frame_id,
                                                            "pose": pose(p, q)})
    t0 = stamp_ns(float(traj.stamps[0]))
    out.write(f"{topic}/path", S.POSES_IN_FRAME, t0, {"timestamp": time_of(t0), "frame_id": frame_id,
                                                      "poses": _poses(traj)})


def write_alignment(out: JsonMcap, t_ns: int, fixed_to_estimate: np.ndarray, *, parent: str, child: str) -> None:
    """The estimate's frame `child` in the fixed frame `parent`: the alignment p_fixed = T p_est."""
    from scipy.spatial.transform import Rotation

    rot = fixed_to_estimate[:3, :3] / np.cbrt(np.linalg.det(fixed_to_estimate[:3, :3]))  # Sim(3) -> its rotation
    q = Rotation.from_matrix(rot).as_quat()
    body = {"timestamp": time_of(t_ns), "parent_frame_id": parent, "child_frame_id": child,
            "translation": pose(fixed_to_estimate[:3, 3])["position"], "rotation": pose((0, 0, 0), q)["orientation"]}
    out.write(f"{ROOT}/tf", S.FRAME_TRANSFORM, t_ns, body)


def write_body_transforms(out: JsonMcap, traj: Trajectory, *, parent: str, child: str) -> None:
    """The SLAM pose at each stamp as the transform parent (estimate frame) -> child (body frame)."""
    for t, p, q in zip(traj.stamps, traj.positions, traj.quat_xyzw, strict=True):
        t_ns = stamp_ns(float(t))
        ps = pose(p, q)
        out.write(f"{ROOT}/tf", S.FRAME_TRANSFORM, t_ns, {
            "timestamp": time_of(t_ns), "parent_frame_id": parent, "child_frame_id": child,
            "translation": ps["position"], "rotation": ps["orientation"]})


ODOM_MAX_GAP_S = 0.05  # an odometry pose farther than this from a SLAM stamp places no odom frame there


def odometry_frame(slam: Trajectory, odom: Trajectory) -> Trajectory | None:
    """The odometry frame in the estimate's frame at each SLAM stamp: P(t) O(t)^-1 with O the
    odometry pose nearest in time (within ODOM_MAX_GAP_S); None when no stamp has one."""
    from mrnc_eval.geometry import lie

    if len(odom) == 0:
        return None
    k = np.searchsorted(odom.stamps, slam.stamps).clip(0, len(odom) - 1)
    prev = (k - 1).clip(0)
    k = np.where(np.abs(odom.stamps[prev] - slam.stamps) <= np.abs(odom.stamps[k] - slam.stamps), prev, k)
    near = np.abs(odom.stamps[k] - slam.stamps) <= ODOM_MAX_GAP_S
    if not near.any():
        return None
    p, o = lie.poses(slam)[near], lie.poses(odom)[k[near]]
    t = p @ np.linalg.inv(o)
    return Trajectory(slam.stamps[near], t[:, :3, 3], lie.matrix_to_quat_xyzw(t[:, :3, :3]), name="odom")


def downsample(xyz: np.ndarray, max_points: int = MAP_POINTS_MAX) -> np.ndarray:
    """One point per voxel, the voxel grown by 1.5x until at most `max_points` remain."""
    xyz = xyz[np.all(np.isfinite(xyz), axis=1)]
    if xyz.shape[0] <= max_points:
        return xyz
    extent = float(np.max(xyz.max(axis=0) - xyz.min(axis=0)))
    voxel = max(extent / 1000.0, 1e-3)  # m
    while True:
        keys = np.floor((xyz - xyz.min(axis=0)) / voxel).astype(np.int64)
        dims = keys.max(axis=0) + 1  # at most ~1001 per axis: the linear voxel index fits in int64
        linear = (keys[:, 0] * dims[1] + keys[:, 1]) * dims[2] + keys[:, 2]
        _, first = np.unique(linear, return_index=True)
        if first.size <= max_points:
            return xyz[np.sort(first)]
        voxel *= 1.5


@dataclass(frozen=True)
class SlamFiles:
    """What a SLAM result directory holds beside result.json, already read."""

    trajectory: Trajectory
    online: Trajectory | None
    keyframes: Trajectory | None
    map_xyz: np.ndarray | None


def write_slam(out: JsonMcap, result: RunResult, files: SlamFiles, *, frame: str) -> int:
    """Estimate(s), APE over time, map, keyframe graph with loop closures, all in the estimate's
    frame `frame` (e.g. lio/map); returns the map points written."""
    topic = f"{ROOT}/slam/{result.extra.get(slam_keys.METHOD, 'lio')}"
    write_trajectory(out, topic, files.trajectory, frame)
    if files.online is not None:
        write_trajectory(out, f"{topic}/online", files.online, frame)
    t0_s = float(files.trajectory.stamps[0])
    t0 = stamp_ns(t0_s)
    schema = S.scalars("mrnc_eval.ApeError", {"ape_m": "position error after SE(3) alignment to the ground "
                                              "truth, m"})
    for sub, which in (("", slam_keys.SMOOTHED), ("/online", slam_keys.ONLINE)):  # smoothed and online estimates
        t_key, err_key = slam_keys.ape_t(which), slam_keys.ape_err(which)
        if t_key not in result.series or err_key not in result.series:
            continue  # no ground truth, no APE
        for t, e in zip(result.series[t_key], result.series[err_key], strict=True):
            t_ns = stamp_ns(t0_s + float(t))
            out.write(f"{topic}{sub}/ape", schema, t_ns, clean({"timestamp": time_of(t_ns), "ape_m": float(e)}))
    written = 0
    if files.map_xyz is not None and files.map_xyz.size:
        cloud = downsample(files.map_xyz)
        written = int(cloud.shape[0])
        out.write(f"{topic}/map", S.POINT_CLOUD, t0, point_cloud(t0, frame, cloud))
    if files.keyframes is not None and len(files.keyframes):
        _write_keyframe_graph(out, f"{topic}/keyframes", files.keyframes, result.events, t0_s, frame)
    return written


def _write_keyframe_graph(out: JsonMcap, topic: str, kf: Trajectory, events: list[Event], t0_s: float,
                          frame: str) -> None:
    """The keyframe chain (line strip) and the loop closures (lines between the two keyframes),
    growing: an update at each shown keyframe's stamp holds the graph up to it."""
    loops = [(t0_s + e.t_s, int(e.data["current"]), int(e.data["previous"])) for e in events
             if e.kind == "loop_closure" and {"current", "previous"} <= set(e.data)]
    n = len(kf)
    shown = np.unique(np.linspace(0, n - 1, min(n, KEYFRAME_UPDATES_MAX)).round().astype(int))
    for k in shown:
        t_s = float(kf.stamps[k])
        t_ns = stamp_ns(t_s)
        lines = [line(S.LINE_STRIP, kf.positions[: k + 1], color(0.2, 0.6, 1.0))]
        closed = [(a, b) for t, a, b in loops if t <= t_s + 1e-6 and max(a, b) < n]
        if closed:
            pairs = np.array([[kf.positions[a], kf.positions[b]] for a, b in closed]).reshape(-1, 3)
            lines.append(line(S.LINE_LIST, pairs, color(1.0, 0.3, 0.1), thickness_px=3.0))
        out.write(topic, S.SCENE_UPDATE, t_ns, {"deletions": [], "entities": [
            line_entity(t_ns, frame, "keyframe_graph", lines)]})


def write_ground_truth(out: JsonMcap, gt: Trajectory, frame: str) -> None:
    """The ground truth in the frame its source declares (`frame`)."""
    write_trajectory(out, f"{ROOT}/ground_truth", gt, frame)


def write_events(out: JsonMcap, result: RunResult, t0_s: float, source: str) -> None:
    """Events at their time and the result's warnings at its start, as foxglove.Log."""
    items = [(t0_s + e.t_s, EVENT_LEVEL.get(e.kind, S.INFO), f"[{e.kind}] {e.message}") for e in result.events]
    items += [(t0_s, S.WARNING, f"[warning] {w}") for w in result.warnings]
    for t_s, level, message in sorted(items, key=lambda item: item[0]):
        t_ns = stamp_ns(t_s)
        out.write(f"{ROOT}/events", S.LOG, t_ns, {"timestamp": time_of(t_ns), "level": level, "message": message,
                                                   "name": source, "file": "", "line": 0})


def write_control(out: JsonMcap, result: RunResult, t0_s: float, *, u_max_rpm: float, saturation_tol_rpm: float,
                  frame: str) -> None:
    """Per controller: references, speeds, errors, funnel, commands, saturation flags and the running
    safety-stop count as one plottable message per stored sample; planned and driven paths in
    `frame` (the frame of the log's path and pose topics: the fixed frame)."""
    schema = S.scalars("mrnc_eval.ControlSample", TRACKING_FIELDS)
    s = result.series
    t0 = stamp_ns(t0_s)
    if result.extra.get(control_keys.MODE) == "sweep":
        return  # per-bin rates, no run over time to play back
    labels = result.extra.get(control_keys.LABELS, {})  # as commands/control labels each controller's events
    for name in result.extra.get(control_keys.CONTROLLERS, []):
        missing = [k for k in (control_keys.time(name), control_keys.funnel(name),
                               *(control_keys.side_series(name, side, q) for side in ("left", "right")
                                 for q in (control_keys.V_REF, control_keys.V_MEAS, control_keys.U_RPM)))
                   if k not in s]
        if missing:  # a renamed series must not drop a controller from the export unseen
            raise InputError(result.log_path, f"control result of {name!r} has no series {', '.join(missing)}")
        topic = f"{ROOT}/control/{name}"
        stops = np.sort([e.t_s for e in result.events if e.kind == "safety_stop"
                         and e.message.startswith((f"{labels.get(name, name)}:", f"{name}:"))])
        t = s[control_keys.time(name)]
        side = {k: {f: s[control_keys.side_series(name, k, f)]
                    for f in (control_keys.V_REF, control_keys.V_MEAS, control_keys.U_RPM)}
                for k in ("left", "right")}
        o = s[control_keys.funnel(name)]
        cte = s.get(control_keys.cte(name))  # None: wheel-speed tracking, no path to measure against
        for i in range(t.size):
            t_ns = stamp_ns(t0_s + float(t[i]))
            body: dict[str, Any] = {
                "timestamp": time_of(t_ns), "funnel_upper_mps": float(o[i]), "funnel_lower_mps": -float(o[i]),
                "cross_track_m": float(cte[i]) if cte is not None else float("nan"),
                "safety_stops": int(np.searchsorted(stops, t[i], side="right"))}
            for k, v in side.items():
                u = float(v[control_keys.U_RPM][i])
                ref, meas = float(v[control_keys.V_REF][i]), float(v[control_keys.V_MEAS][i])
                body.update({f"v_ref_{k}_mps": ref, f"v_{k}_mps": meas, f"error_{k}_mps": meas - ref, f"u_{k}_rpm": u,
                             f"saturated_{k}": int(abs(u) >= u_max_rpm - saturation_tol_rpm)})
            out.write(f"{topic}/tracking", schema, t_ns, clean(body))
        planned = s.get(control_keys.PATH_XY)
        if planned is not None and planned.size:
            out.write(f"{topic}/planned_path", S.POSES_IN_FRAME, t0, _path_2d(t0, planned, frame))
        if control_keys.driven_xy(name) in s:  # absent: wheel-speed tracking of a log without a pose topic
            out.write(f"{topic}/driven_path", S.POSES_IN_FRAME, t0,
                      _path_2d(t0, s[control_keys.driven_xy(name)], frame))


def _path_2d(t_ns: int, xy: np.ndarray, frame: str) -> dict[str, Any]:
    """Planar path: heading along the path (the last point keeps the previous heading)."""
    d = np.diff(xy, axis=0, append=xy[-1:] + (xy[-1:] - xy[-2:-1] if len(xy) > 1 else 0.0))
    yaw = np.arctan2(d[:, 1], d[:, 0])
    return {"timestamp": time_of(t_ns), "frame_id": frame,
            "poses": [pose((x, y, 0.0), (0.0, 0.0, np.sin(a / 2), np.cos(a / 2)))
                      for (x, y), a in zip(xy, yaw, strict=True)]}
