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

from mrnc_eval.control.config import PurePursuitConfig
from mrnc_eval.control.jit_cache import FloatArray, kernel

# Parameter vector of the compiled step, packed once by `pure_pursuit_params` (slot names below).
(PP_LOOKAHEAD, PP_DESIRED_V, PP_MAX_V, PP_ROBOT_MAX_V, PP_TRACK, PP_LITERAL, PP_CAP, PP_WINDOW, PP_GOAL_TOL,
 PP_APPROACH_DIST, PP_MIN_APPROACH_V, PP_SCALED, PP_LA_TIME, PP_LA_MIN, PP_LA_MAX) = range(15)
PP_SIZE = 15


def pure_pursuit_params(cfg: PurePursuitConfig, track_width_m: float, robot_max_speed_mps: float) -> FloatArray:
    """Pack the path-following settings (and the robot's track Lr, m, and top speed, m/s) for `pp_step`."""
    p = np.zeros(PP_SIZE)
    p[PP_LOOKAHEAD] = cfg.lookahead_m
    p[PP_DESIRED_V] = cfg.desired_speed_mps
    p[PP_MAX_V] = cfg.max_speed_mps
    p[PP_ROBOT_MAX_V] = robot_max_speed_mps
    p[PP_TRACK] = track_width_m
    p[PP_LITERAL] = 1.0 if cfg.curvature == "paper_literal" else 0.0
    p[PP_CAP] = 1.0 if cfg.speed_cap else 0.0
    p[PP_WINDOW] = float(cfg.search_window)
    p[PP_GOAL_TOL] = cfg.goal_tolerance_m
    p[PP_APPROACH_DIST] = cfg.approach_distance_m
    p[PP_MIN_APPROACH_V] = cfg.min_approach_speed_mps
    p[PP_SCALED] = 1.0 if cfg.velocity_scaled_lookahead else 0.0
    p[PP_LA_TIME] = cfg.lookahead_time_s
    p[PP_LA_MIN] = cfg.lookahead_min_m
    p[PP_LA_MAX] = cfg.lookahead_max_m
    return p


@kernel
def wrap_angle(a: float) -> float:
    # into (-pi, pi]
    return a - 2.0 * math.pi * math.ceil((a - math.pi) / (2.0 * math.pi))


@kernel
def _project(px: float, py: float, ax: float, ay: float, bx: float, by: float) -> tuple[float, float, float]:
    """Closest point of segment a-b to p: (fraction along the segment in [0, 1], x, y)."""
    dx, dy = bx - ax, by - ay
    L2 = dx * dx + dy * dy
    if L2 <= 0.0:
        return 0.0, ax, ay
    s = ((px - ax) * dx + (py - ay) * dy) / L2
    s = min(max(s, 0.0), 1.0)
    return s, ax + s * dx, ay + s * dy


@kernel
def _closest_segment(x: float, y: float, wp: FloatArray, idx: int, window: int) -> int:
    """Closest segment to (x, y), searched forward only from idx within `window` segments."""
    best, best_d = idx, 1e300
    for k in range(idx, min(idx + window, wp.shape[0] - 1)):
        _, qx, qy = _project(x, y, wp[k, 0], wp[k, 1], wp[k + 1, 0], wp[k + 1, 1])
        d = (qx - x) ** 2 + (qy - y) ** 2
        if d < best_d - 1e-12:
            best, best_d = k, d
    return best


@kernel
def _remaining_length(wp: FloatArray, idx: int, qx: float, qy: float) -> float:
    """Path length (m) from the projection (qx, qy) on segment idx to the last waypoint."""
    remaining = math.hypot(wp[idx + 1, 0] - qx, wp[idx + 1, 1] - qy)
    for k in range(idx + 1, wp.shape[0] - 1):
        remaining += math.hypot(wp[k + 1, 0] - wp[k, 0], wp[k + 1, 1] - wp[k, 1])
    return remaining


@kernel
def _carrot(x: float, y: float, wp: FloatArray, idx: int, qx: float, qy: float, L: float) -> tuple[float, float]:
    """First point from the projection onwards at Euclidean distance L from (x, y); else the goal."""
    n = wp.shape[0]
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
            return ax + t * dx, ay + t * dy
        ax, ay = bx, by
    return wp[n - 1, 0], wp[n - 1, 1]


@kernel
def _speed_and_yaw_rate(alpha: float, D: float, L: float, remaining: float, p: FloatArray) -> tuple[float, float]:
    """(v m/s, omega rad/s) toward a carrot at bearing alpha (rad) and distance D (m), lookahead L (m)."""
    track = p[PP_TRACK]
    v = min(p[PP_DESIRED_V], p[PP_MAX_V])
    delta = math.atan(2.0 * L * math.sin(alpha) / D)
    # the paper's printed form 2 tan(delta) / D, or Coulter's 2 sin(alpha) / D
    kappa = 2.0 * math.tan(delta) / D if p[PP_LITERAL] > 0.5 else 2.0 * math.sin(alpha) / D
    if p[PP_CAP] > 0.5:
        v = min(v, p[PP_ROBOT_MAX_V] / (2.0 * (1.0 + abs(math.tan(delta)) * track / D)))
    if remaining < p[PP_APPROACH_DIST]:
        v = min(v, max(v * remaining / p[PP_APPROACH_DIST], p[PP_MIN_APPROACH_V]))
    omega = 0.0 if kappa == 0.0 else v * kappa
    # keep both sides' speeds under max_v (curvature preserved): the pumps cannot deliver more
    side = abs(v) + 0.5 * abs(omega) * track
    if side > p[PP_MAX_V]:
        v *= p[PP_MAX_V] / side
        omega *= p[PP_MAX_V] / side
    return v, omega


@kernel
def pp_step(x: float, y: float, yaw: float, v_meas: float, wp: FloatArray, idx: int,
            p: FloatArray) -> tuple[float, float, int, bool, float, float]:
    """One pure pursuit update with the packed parameters `p` (see `pure_pursuit_params`).
    Returns (v m/s, omega rad/s, segment index, done, carrot_x m, carrot_y m)."""
    n = wp.shape[0]
    gx, gy = wp[n - 1, 0], wp[n - 1, 1]
    idx = _closest_segment(x, y, wp, idx, int(p[PP_WINDOW]))
    s0, qx, qy = _project(x, y, wp[idx, 0], wp[idx, 1], wp[idx + 1, 0], wp[idx + 1, 1])
    remaining = _remaining_length(wp, idx, qx, qy)
    if idx == n - 2 and (s0 >= 1.0 or math.hypot(gx - x, gy - y) < p[PP_GOAL_TOL]):
        return 0.0, 0.0, idx, True, gx, gy
    L = p[PP_LOOKAHEAD]
    if p[PP_SCALED] > 0.5:
        L = min(max(abs(v_meas) * p[PP_LA_TIME], p[PP_LA_MIN]), p[PP_LA_MAX])
    cx, cy = _carrot(x, y, wp, idx, qx, qy, L)
    D = math.hypot(cx - x, cy - y)
    if D < 1e-6:
        return 0.0, 0.0, idx, True, gx, gy
    alpha = wrap_angle(math.atan2(cy - y, cx - x) - yaw)
    v, omega = _speed_and_yaw_rate(alpha, D, L, remaining, p)
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
        self._params = pure_pursuit_params(self.cfg, self.track_width_m, self.robot_max_speed_mps)

    def step(self, x: float, y: float, yaw: float, v_meas: float = 0.0) -> tuple[float, float, float, float]:
        """(v m/s, omega rad/s, carrot x m, carrot y m); zero speeds once the goal was reached."""
        v, w, self.index, done, cx, cy = pp_step(x, y, yaw, v_meas, self.waypoints, self.index, self._params)
        self.done = self.done or done
        if self.done:
            return 0.0, 0.0, cx, cy
        return v, w, cx, cy
