"""The paper's circle experiment and other scripted paths, as waypoints + slip patches."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mrnc_eval.control.config import ControlConfig
from mrnc_eval.control.plant import SlipPatch


@dataclass(frozen=True)
class Scenario:
    name: str
    waypoints_xy: np.ndarray  # (N, 2) m
    slip_patches: tuple[SlipPatch, ...]
    start_pose: tuple[float, float, float]  # x m, y m, yaw rad


def paper_circle_scenario(cfg: ControlConfig) -> Scenario:
    """The paper's experiment: 8 waypoints on a 5 m circle driven once clockwise (the paper:
    "the robot has the right side heading on the circle", the left side runs faster) and closed
    back to the start; the robot starts on the first waypoint facing along the circle. The
    centre and slip patches follow the paper's GPS figure (see control.scenario in the config)."""
    s = cfg.scenario
    cx, cy = s.centre_xy_m
    a0 = math.radians(s.start_angle_deg)
    ang = a0 - 2 * math.pi * np.arange(s.n_waypoints + 1) / s.n_waypoints
    wp = np.c_[cx + s.circle_radius_m * np.cos(ang), cy + s.circle_radius_m * np.sin(ang)]
    patches = tuple(SlipPatch(p.x_m, p.y_m, p.radius_m, p.slip) for p in s.slip_patches)
    heading = math.atan2(wp[1, 1] - wp[0, 1], wp[1, 0] - wp[0, 0])  # along the first chord
    return Scenario("circle", wp, patches, (float(wp[0, 0]), float(wp[0, 1]), heading))


def waypoint_scenario(waypoints_xy: np.ndarray, name: str = "waypoints") -> Scenario:
    """A path without slip, started on its first waypoint facing the second."""
    wp = np.asarray(waypoints_xy, dtype=np.float64).reshape(-1, 2)
    if wp.shape[0] < 2:
        raise ValueError("a path needs at least 2 waypoints")
    yaw0 = math.atan2(wp[1, 1] - wp[0, 1], wp[1, 0] - wp[0, 0])
    return Scenario(name, wp, (), (float(wp[0, 0]), float(wp[0, 1]), yaw0))


def scripted_scenario(name: str, cfg: ControlConfig, *, size_m: float = 10.0) -> Scenario:
    """figure8, loop (a rounded rectangle that returns to its start), line."""
    if name == "circle":
        return paper_circle_scenario(cfg)
    if name == "figure8":
        u = np.linspace(0, 2 * math.pi, 33)
        wp = np.c_[size_m * np.sin(u), size_m / 2 * np.sin(2 * u)]
    elif name == "loop":
        a, b, r = size_m, size_m * 0.6, size_m * 0.2
        pts = []
        for cx, cy, a0 in ((a - r, r, -math.pi / 2), (a - r, b - r, 0.0), (r, b - r, math.pi / 2), (r, r, math.pi)):
            for k in range(5):
                t = a0 + k * (math.pi / 2) / 4
                pts.append((cx + r * math.cos(t), cy + r * math.sin(t)))
        wp = np.asarray(pts + [pts[0]])
        wp = wp - wp[0]
    elif name == "line":
        wp = np.c_[np.linspace(0, size_m, 11), np.zeros(11)]
    else:
        raise ValueError(f"unknown path {name!r}: circle, figure8, loop, line")
    return waypoint_scenario(wp, name)
