"""Replay of a recorded run: the references the chain would have issued along the recorded pose
(pure pursuit at its rate, inverse kinematics, the reference slew), or without a path the inverse
kinematics of the recorded twist, and the recording as a ClosedLoopTrace that the simulation's
metrics evaluate. Pure: takes the streams already read (io/control_recording.py reads them)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.control.closed_loop import ClosedLoopTrace
from mrnc_eval.control.config import ControlConfig, RobotGeometry, reference_accel_limit
from mrnc_eval.control.jit_cache import FloatArray
from mrnc_eval.control.kinematics import inverse_kinematics, slew
from mrnc_eval.control.pure_pursuit import PurePursuit
from mrnc_eval.control.raid import funnel_series
from mrnc_eval.control.wheel_references import wheel_speed_references
from mrnc_eval.data import SidePair, Twists
from mrnc_eval.evaluation.control_metrics import estimate_slip

WHEEL_SPEED_TRACKING = "wheel-speed tracking (no path)"  # how a replay of a log without a path is labelled
Pose = tuple[FloatArray, FloatArray, FloatArray, FloatArray]  # t s, x m, y m, yaw rad


@dataclass(frozen=True)
class Recording:
    """What a control replay reads from a log: a path to follow (the log's, or --path) and the
    recorded pose, or without a path the body twist whose inverse kinematics the wheels tracked."""

    waypoints: FloatArray | None  # (N, 2) m; None: wheel-speed tracking
    pose: Pose | None  # None: no pose topic (allowed without a path)
    pose_source: str
    speeds: SidePair  # wheel surface speeds, m/s
    commands: SidePair | None  # pump commands, RPM
    health_notes: tuple[str, ...] = ()  # samples dropped, stamps sorted while reading
    roles: Mapping[str, str] = field(default_factory=dict)  # role -> topic of the log
    twists: Twists | None = None  # wheel-speed tracking: cmd_vel, else the wheel odometry's twist
    twist_role: str = ""  # "cmd_vel" or "wheel_odom"
    path_source: str = ""  # the path topic, or the --path file


def evaluated(rec: Recording) -> NDArray[np.bool_]:
    """Which wheel-speed samples a replay evaluates: all when following a path, those inside the
    recorded twist's span in wheel-speed tracking."""
    t = rec.speeds.stamps
    if rec.twists is None:
        return np.ones(t.size, bool)
    inside: NDArray[np.bool_] = (t >= rec.twists.stamps[0]) & (t <= rec.twists.stamps[-1])
    return inside


def replay_roles(rec: Recording) -> dict[str, str]:
    """role -> topic (or --path file) of what a replay read, for summaries and reports."""
    used = {"path": rec.path_source} if rec.path_source else {}
    for role in (rec.twist_role, rec.pose_source, "wheel_speeds", "commands"):
        if role and role in rec.roles and role not in used:
            used[role] = rec.roles[role]
    return used


def replay_references(t: FloatArray, px: FloatArray, py: FloatArray, pyaw: FloatArray, speeds: SidePair,
                      wp: FloatArray, cfg: ControlConfig, robot: RobotGeometry) -> tuple[FloatArray, bool, float]:
    """Per-side references (N, 2) m/s that pure pursuit (at its rate), inverse kinematics and the
    reference slew issue along the recorded pose; whether and when (s after the start) it finished."""
    pp = PurePursuit(wp, cfg.pure_pursuit, robot.track_width_m, robot.max_speed_mps)
    v_ref = np.zeros((t.size, 2))
    next_pp, tl, tr_, vl, vr = t[0], 0.0, 0.0, 0.0, 0.0
    done_at = float("nan")
    accel = reference_accel_limit(cfg)
    for k in range(t.size):
        if t[k] >= next_pp:
            v, w, _, _ = pp.step(px[k], py[k], pyaw[k], 0.5 * (speeds.left[k] + speeds.right[k]))
            tl, tr_ = inverse_kinematics(v, w, robot.track_width_m)
            next_pp = t[k] + 1.0 / cfg.pure_pursuit.rate_hz
            if pp.done and math.isnan(done_at):
                done_at = t[k] - t[0]
        dt_k = t[k] - t[k - 1] if k else 0.0
        vl, vr = slew(vl, tl, accel, dt_k), slew(vr, tr_, accel, dt_k)
        v_ref[k] = vl, vr
    return v_ref, pp.done, done_at


def body_rates(t: FloatArray, x: FloatArray, y: FloatArray, yaw: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Forward speed (m/s, along the heading) and yaw rate (rad/s) of a recorded pose."""
    vx, vy = np.gradient(x, t), np.gradient(y, t)
    return vx * np.cos(yaw) + vy * np.sin(yaw), np.gradient(yaw, t)


def replay_slip(t: FloatArray, px: FloatArray, py: FloatArray, pyaw: FloatArray, speeds: SidePair,
                source: str, track_width_m: float) -> tuple[FloatArray, FloatArray]:
    """Slip patches per side from wheel vs ground speed (zeros from wheel odometry, which moves with
    the wheels and cannot show slip)."""
    if source == "wheel_odom":
        return np.zeros_like(t), np.zeros_like(t)
    v_body, w_body = body_rates(t, px, py, pyaw)
    half = 0.5 * track_width_m
    return (estimate_slip(t, speeds.left, v_body - w_body * half),
            estimate_slip(t, speeds.right, v_body + w_body * half))


def commands_at(t: FloatArray, cmds: SidePair | None) -> tuple[FloatArray, FloatArray]:
    """Recorded pump commands (RPM) at the stamps t; zeros without a command topic."""
    if cmds is None:
        return np.zeros_like(t), np.zeros_like(t)
    return np.interp(t, cmds.stamps, cmds.left), np.interp(t, cmds.stamps, cmds.right)


def replay_trace(rec: Recording, cfg: ControlConfig, robot: RobotGeometry) -> tuple[ClosedLoopTrace, list[str]]:
    """The recording as a trace against the recomputed references, and the replay's warnings."""
    if rec.waypoints is None:
        return wheel_speed_tracking(rec, cfg, robot)
    assert rec.pose is not None  # the reader requires it with a path
    warnings: list[str] = list(rec.health_notes)
    if rec.pose_source != "ground_truth":
        warnings.append(f"recorded pose from {rec.pose_source} (no ground truth): it must be in the frame of the path")
    if rec.commands is None:
        warnings.append("no pump-command topic: command metrics (saturation, effort) are zero")
    speeds = rec.speeds
    t = speeds.stamps
    pt, pxs, pys, pyaws = rec.pose
    px, py = np.interp(t, pt, pxs), np.interp(t, pt, pys)
    pyaw = np.interp(t, pt, np.unwrap(pyaws))
    v_ref, done, done_at = replay_references(t, px, py, pyaw, speeds, rec.waypoints, cfg, robot)
    u_l, u_r = commands_at(t, rec.commands)
    slip_l, slip_r = replay_slip(t, px, py, pyaw, speeds, rec.pose_source, robot.track_width_m)
    zeros = np.zeros_like(t)
    tr = ClosedLoopTrace(controller="recorded", label=f"recorded ({rec.pose_source})", t=t - t[0], x=px, y=py,
                         yaw=pyaw, v=zeros, omega=zeros, cmd_v=zeros, cmd_omega=zeros,
                         v_ref_left=v_ref[:, 0], v_ref_right=v_ref[:, 1],
                         v_wheel_left=speeds.left, v_wheel_right=speeds.right, slip_left=slip_l, slip_right=slip_r,
                         u_left=u_l, u_right=u_r, funnel=funnel_series(t - t[0], cfg), completed=done,
                         completion_time_s=done_at, waypoints=rec.waypoints)
    return tr, warnings


def wheel_speed_tracking(rec: Recording, cfg: ControlConfig,
                         robot: RobotGeometry) -> tuple[ClosedLoopTrace, list[str]]:
    """No path: the recorded wheel speeds against the inverse kinematics (track robot.track_width_m)
    of the recorded cmd_vel, held between messages and slewed as the chain slews its references,
    or of the wheel odometry's twist (a measurement: interpolated, not slewed); evaluated where the
    twist is recorded, with the path replay's per-side metrics."""
    assert rec.twists is not None  # the reader reads them when there is no path
    tw, role = rec.twists, rec.twist_role
    warnings = list(rec.health_notes)
    if role != "cmd_vel":
        warnings.append("references from the wheel odometry's twist (no cmd_vel topic): an odometry computed from "
                        "these wheel speeds agrees with them by construction, so the error then shows only timing "
                        "and track-width differences, not tracking")
    if rec.commands is None:
        warnings.append("no pump-command topic: command metrics (saturation, effort) are zero")
    inside = evaluated(rec)
    if not inside.all():
        warnings.append(f"{int(np.count_nonzero(~inside))} wheel-speed samples outside the {role} span not evaluated")
    t = rec.speeds.stamps[inside]
    speeds = SidePair(t, rec.speeds.left[inside], rec.speeds.right[inside], rec.speeds.unit)
    v_ref = wheel_speed_references(t, tw.stamps, tw.v, tw.omega, robot.track_width_m, held=role == "cmd_vel",
                                   accel_limit_mps2=reference_accel_limit(cfg),
                                   start=(float(speeds.left[0]), float(speeds.right[0])))
    x = y = yaw = np.full_like(t, np.nan)
    slip_l = slip_r = np.zeros_like(t)
    if rec.pose is not None:
        pt, pxs, pys, pyaws = rec.pose
        x, y, yaw = np.interp(t, pt, pxs), np.interp(t, pt, pys), np.interp(t, pt, np.unwrap(pyaws))
        slip_l, slip_r = replay_slip(t, x, y, yaw, speeds, rec.pose_source, robot.track_width_m)
    u_l, u_r = commands_at(t, rec.commands)
    zeros = np.zeros_like(t)
    label = f"recorded: {WHEEL_SPEED_TRACKING}, references from {role} {rec.roles.get(role, '')}".rstrip()
    tr = ClosedLoopTrace(controller="recorded", label=label, t=t - t[0], x=x, y=y, yaw=yaw, v=zeros, omega=zeros,
                         cmd_v=np.interp(t, tw.stamps, tw.v), cmd_omega=np.interp(t, tw.stamps, tw.omega),
                         v_ref_left=v_ref[:, 0], v_ref_right=v_ref[:, 1], v_wheel_left=speeds.left,
                         v_wheel_right=speeds.right, slip_left=slip_l, slip_right=slip_r, u_left=u_l, u_right=u_r,
                         funnel=funnel_series(t - t[0], cfg))
    return tr, warnings
