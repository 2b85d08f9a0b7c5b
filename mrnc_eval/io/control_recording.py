"""Reading what a control replay (or a simulation along a log's path) needs from a log: the path,
the recorded pose, wheel speeds, pump commands, and without a path the body twist. Errors name the
log, the topic and the problem; the computation is in control/replay.py."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from mrnc_eval.control.config import ControlConfig
from mrnc_eval.control.replay import Pose, Recording, evaluated
from mrnc_eval.control.scenario import Scenario, paper_circle_scenario
from mrnc_eval.data import SidePair, Twists, Waypoints
from mrnc_eval.errors import InputError
from mrnc_eval.geometry.lie import quat_xyzw_to_matrix, yaw_pitch_roll_sxyz
from mrnc_eval.io import open_log
from mrnc_eval.io.config import IoConfig


def _yaw(quat_xyzw: np.ndarray) -> np.ndarray:
    """Heading (rad) of (N, 4) xyzw orientations, by the project's one quaternion-to-Euler path."""
    return np.asarray(yaw_pitch_roll_sxyz(quat_xyzw_to_matrix(quat_xyzw))[0])


def scenario_from_log(log_path: Path, io_cfg: IoConfig, cfg: ControlConfig) -> tuple[Scenario, dict[str, str]]:
    """The log's path as a scenario (the paper circle's slip patches), and the log's roles (role -> topic)."""
    with open_log(log_path, io_cfg) as lg:
        roles = dict(lg.roles)
        wp = lg.waypoints().xy
        start = lg.ground_truth() if lg.has_role("ground_truth") else None
    if start is not None:
        pose = (float(start.positions[0, 0]), float(start.positions[0, 1]), float(_yaw(start.quat_xyzw[:1])[0]))
    else:
        pose = (float(wp[0, 0]), float(wp[0, 1]), math.atan2(wp[1, 1] - wp[0, 1], wp[1, 0] - wp[0, 0]))
    base = paper_circle_scenario(cfg)
    return Scenario(f"path of {log_path.name}", wp, base.slip_patches, pose), roles


def recorded_pose(lg: Any, log_path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, str]:
    """(t, x, y, yaw, source) of the recorded motion: ground truth, else wheel odometry, else
    GNSS (ENU; heading from the track direction). The pose must be in the frame of the path."""
    roles = lg.roles
    if "ground_truth" in roles or "wheel_odom" in roles:
        source = "ground_truth" if "ground_truth" in roles else "wheel_odom"
        traj = lg.ground_truth() if source == "ground_truth" else lg.wheel_odometry()
        return traj.stamps, traj.positions[:, 0], traj.positions[:, 1], _yaw(traj.quat_xyzw), source
    if "gnss" in roles:
        g = lg.gnss()
        if g.stamps.size < 3:
            raise InputError(log_path, "too few GNSS fixes to replay the path", topic=roles["gnss"])
        e, n = g.enu[:, 0], g.enu[:, 1]
        yaw = np.arctan2(np.gradient(n), np.gradient(e))  # track direction; the robot drives forwards
        return g.stamps, e, n, yaw, "gnss"
    raise InputError(log_path, "control replay needs the recorded pose: a ground-truth, wheel-odometry or GNSS topic "
                               "(none found; set io.roles.ground_truth, io.roles.wheel_odom or io.roles.gnss)")


def read_recording(log_path: Path, io_cfg: IoConfig, wheel_radius_m: float, path: Waypoints | None = None,
                   path_source: str = "") -> Recording:
    """The streams of a replay; `path` (from --path, named `path_source`) replaces the log's path topic."""
    with open_log(log_path, io_cfg) as lg:
        roles = lg.roles
        if "wheel_speeds" not in roles:
            raise InputError(log_path, "control replay needs a wheel_speeds topic (none found; set "
                                       "io.roles.wheel_speeds)")
        if path is None and "path" in roles:
            path, path_source = lg.waypoints(), roles["path"]
        twists, twist_role = None, ""
        if path is None:
            twists, twist_role = _tracking_twists(lg, log_path)
        pose, source, pose_note = _pose_if_any(lg, log_path, required=path is not None)
        speeds = lg.wheel_speeds(wheel_radius_m=wheel_radius_m)
        cmds = lg.commands() if "commands" in roles else None
        notes = (*lg.health_notes(), *pose_note)  # samples dropped, stamps sorted: said in the result
    wp = path.xy if path is not None else None
    if wp is not None and wp.shape[0] < 2:
        raise InputError(log_path, "the planned path has fewer than 2 waypoints", topic=roles.get("path"))
    if speeds.stamps.size < 3:
        raise InputError(log_path, "too few wheel-speed messages to evaluate tracking", topic=roles["wheel_speeds"])
    rec = Recording(waypoints=wp, pose=pose, pose_source=source, speeds=speeds, commands=cmds, health_notes=notes,
                    roles=dict(roles), twists=twists, twist_role=twist_role, path_source=path_source)
    if np.count_nonzero(evaluated(rec)) < 3:
        raise InputError(log_path, f"the {twist_role} messages do not overlap the wheel speeds ("
                                   f"{roles['wheel_speeds']}) in time: nothing to evaluate", topic=roles[twist_role])
    return rec


def _pose_if_any(lg: Any, log_path: Path, *, required: bool) -> tuple[Pose | None, str, tuple[str, ...]]:
    """The recorded pose and its source: required to follow a path; without one it only places the
    run and shows slip, so a log without a usable pose topic is evaluated anyway (and says so)."""
    if not required and not any(r in lg.roles for r in ("ground_truth", "wheel_odom", "gnss")):
        return None, "", ("no pose topic (ground truth, wheel odometry or GNSS): slip not estimated",)
    try:
        pt, pxs, pys, pyaws, source = recorded_pose(lg, log_path)
    except InputError as err:
        if required:
            raise
        return None, "", (f"recorded pose not used ({err}): slip not estimated",)
    return (pt, pxs, pys, pyaws), source, ()


def _tracking_twists(lg: Any, log_path: Path) -> tuple[Twists, str]:
    """The body twist wheel-speed tracking is measured against: the recorded cmd_vel, else the
    wheel odometry's twist."""
    roles = lg.roles
    for role, read in (("cmd_vel", lg.cmd_vel), ("wheel_odom", lg.odometry_twist)):
        if role in roles:
            tw = read()
            if tw.stamps.size < 2:
                raise InputError(log_path, "too few messages for wheel-speed tracking", topic=roles[role])
            return tw, role
    raise InputError(log_path, "control replay needs a path to follow (a path topic, or --path FILE with TUM or CSV "
                               "waypoints) or, for wheel-speed tracking without one, a cmd_vel or wheel-odometry "
                               "topic (none found; set io.roles.path, io.roles.cmd_vel or io.roles.wheel_odom)")


def read_drive_record(log_path: Path, io_cfg: IoConfig,
                      wheel_radius_m: float) -> tuple[SidePair, SidePair, dict[str, str]]:
    """Wheel speeds (m/s) and pump commands (RPM) per side for identifying the drive, and the topics."""
    with open_log(log_path, io_cfg) as lg:
        roles = dict(lg.roles)
        if "commands" not in roles:
            raise InputError(log_path, "control --mode identify needs the pump commands: no commands topic found "
                                       "(JointState per side, RPM; set io.roles.commands)")
        if "wheel_speeds" not in roles:
            raise InputError(log_path, "control --mode identify needs the wheel speeds: no wheel_speeds topic found "
                                       "(set io.roles.wheel_speeds)")
        speeds = lg.wheel_speeds(wheel_radius_m=wheel_radius_m)
        cmds = lg.commands()
    if speeds.stamps.size < 50 or cmds.stamps.size < 2:
        raise InputError(log_path, f"too few messages to identify the drive ({speeds.stamps.size} wheel speeds, "
                                   f"{cmds.stamps.size} commands)", topic=roles["commands"])
    return speeds, cmds, {r: roles[r] for r in ("wheel_speeds", "commands")}
