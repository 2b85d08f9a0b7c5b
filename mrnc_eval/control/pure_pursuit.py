"""Pure pursuit for a skid-steer robot (paper-notes 3; control-reference 1).

- alpha is the carrot bearing relative to the heading, wrapped to (-pi, pi];
- curvature from the actual carrot distance D: kappa = 2 sin(alpha) / D (standard) or the
  paper's printed delta = atan(2 L sin(alpha) / D), kappa = 2 tan(delta) / D (paper_literal);
- the segment index only moves forward, searched in a bounded window, so a closed loop
  such as the paper's circle cannot jump across;
- the carrot is interpolated on the path at Euclidean distance L from the robot;
- the robot slows inside the approach distance and stops at the goal (v = omega = 0).
The kernel is compiled (numba) so the closed-loop simulation can call it at 50 Hz for hours.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from mrnc_eval.control.config import PurePursuitConfig


@njit(cache=True)
def wrap_angle(a: float) -> float:
    # into (-pi, pi]
    return a - 2.0 * math.pi * math.ceil((a - math.pi) / (2.0 * math.pi))


@njit(cache=True)
def _project(px, py, ax, ay, bx, by):
    dx, dy = bx - ax, by - ay
    L2 = dx * dx + dy * dy
    if L2 <= 0.0:
        return 0.0, ax, ay
    s = ((px - ax) * dx + (py - ay) * dy) / L2
    s = min(max(s, 0.0), 1.0)
    return s, ax + s * dx, ay + s * dy


@njit(cache=True)
def pp_step(x, y, yaw, v_meas, wp, idx, lookahead, desired_v, max_v, robot_max_v, track, literal, cap,
            window, goal_tol, approach_dist, min_approach_v, scaled, la_time, la_min, la_max):
    """One pure pursuit update. Returns (v, omega, idx, done, carrot_x, carrot_y)."""
    n = wp.shape[0]
    gx, gy = wp[n - 1, 0], wp[n - 1, 1]
    # closest segment, forward only, bounded window
    best, best_d = idx, 1e300
    for k in range(idx, min(idx + window, n - 1)):
        _, qx, qy = _project(x, y, wp[k, 0], wp[k, 1], wp[k + 1, 0], wp[k + 1, 1])
        d = (qx - x) ** 2 + (qy - y) ** 2
        if d < best_d - 1e-12:
            best, best_d = k, d
    idx = best
    s0, qx, qy = _project(x, y, wp[idx, 0], wp[idx, 1], wp[idx + 1, 0], wp[idx + 1, 1])
    # remaining path length from the projection
    remaining = math.hypot(wp[idx + 1, 0] - qx, wp[idx + 1, 1] - qy)
    for k in range(idx + 1, n - 1):
        remaining += math.hypot(wp[k + 1, 0] - wp[k, 0], wp[k + 1, 1] - wp[k, 1])
    dist_goal = math.hypot(gx - x, gy - y)
    if idx == n - 2 and (s0 >= 1.0 or dist_goal < goal_tol):
        return 0.0, 0.0, idx, True, gx, gy
    L = lookahead
    if scaled:
        L = min(max(abs(v_meas) * la_time, la_min), la_max)
    # carrot: first point from the projection onwards at Euclidean distance >= L
    cx, cy = gx, gy
    ax, ay = qx, qy
    for k in range(idx, n - 1):
        bx, by = wp[k + 1, 0], wp[k + 1, 1]
        if (bx - x) ** 2 + (by - y) ** 2 >= L * L:
            # solve |a + t (b - a) - p| = L for t in [0, 1]
            dx, dy = bx - ax, by - ay
            fx, fy = ax - x, ay - y
            A = dx * dx + dy * dy
            B = 2.0 * (fx * dx + fy * dy)
            C = fx * fx + fy * fy - L * L
            disc = B * B - 4.0 * A * C
            t = 1.0
            if A > 0.0 and disc >= 0.0:
                t = (-B + math.sqrt(disc)) / (2.0 * A)
                t = min(max(t, 0.0), 1.0)
            cx, cy = ax + t * dx, ay + t * dy
            break
        ax, ay = bx, by
    D = math.hypot(cx - x, cy - y)
    alpha = wrap_angle(math.atan2(cy - y, cx - x) - yaw)
    v = min(desired_v, max_v)
    if D < 1e-6:
        return 0.0, 0.0, idx, True, gx, gy
    if literal:
        delta = math.atan(2.0 * L * math.sin(alpha) / D)
        kappa = 2.0 * math.tan(delta) / D
    else:
        delta = math.atan(2.0 * L * math.sin(alpha) / D)
        kappa = 2.0 * math.sin(alpha) / D
    if cap:
        v = min(v, robot_max_v / (2.0 * (1.0 + abs(math.tan(delta)) * track / D)))
    if remaining < approach_dist:
        v = min(v, max(v * remaining / approach_dist, min_approach_v))
    omega = 0.0 if kappa == 0.0 else v * kappa
    # keep both sides' speeds under max_v (curvature preserved): the pumps cannot deliver more
    side = abs(v) + 0.5 * abs(omega) * track
    if side > max_v:
        v *= max_v / side
        omega *= max_v / side
    return v, omega, idx, False, cx, cy


@dataclass
class PurePursuit:
    """Stateful wrapper: call `step(x, y, yaw)` at the path-following rate."""

    waypoints: np.ndarray
    cfg: PurePursuitConfig
    track_width_m: float
    robot_max_speed_mps: float
    index: int = 0
    done: bool = False

    def __post_init__(self) -> None:
        self.waypoints = np.ascontiguousarray(self.waypoints, dtype=np.float64)
        if self.waypoints.ndim != 2 or self.waypoints.shape[0] < 2:
            raise ValueError("pure pursuit needs at least 2 waypoints")

    def step(self, x: float, y: float, yaw: float, v_meas: float = 0.0) -> tuple[float, float, float, float]:
        c = self.cfg
        v, w, self.index, done, cx, cy = pp_step(
            x, y, yaw, v_meas, self.waypoints, self.index, c.lookahead_m, c.desired_speed_mps, c.max_speed_mps,
            self.robot_max_speed_mps, self.track_width_m, c.curvature == "paper_literal", c.speed_cap,
            c.search_window, c.goal_tolerance_m, c.approach_distance_m, c.min_approach_speed_mps,
            c.velocity_scaled_lookahead, c.lookahead_time_s, c.lookahead_min_m, c.lookahead_max_m)
        self.done = self.done or done
        if self.done:
            return 0.0, 0.0, cx, cy
        return v, w, cx, cy
