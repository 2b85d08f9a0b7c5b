"""Ground-truth body motion: the closed-loop trace (x, y, yaw at the control rate) as cubic
splines, lifted onto the terrain. z follows the heightfield and the body's up axis is the exact
terrain normal, so pitch and roll follow the ground. Every quantity is a smooth function of
time, so IMU derivatives and LiDAR per-column poses agree with the ground truth. An optional
`Shake` adds the body's bounce, roll and pitch after its wheels roll over stones (field profile)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from mrnc_eval.sim.scene import Terrain

BASE_HEIGHT_M = 0.6  # base_link above the ground contact, along the terrain normal's vertical
GRAVITY_MPS2 = 9.80665  # standard gravity, m/s^2 (world z up)
FD_STEP_S = 1e-3  # central-difference step on the splines, s


@dataclass(frozen=True)
class Shake:
    """Body bounce (m), roll and pitch (rad) from stones under single wheels, as smooth functions
    of time (cubic splines through the simulated response; zero outside it)."""

    t: np.ndarray  # (N,) s
    splines: tuple[Any, Any, Any]  # three CubicSplines: z, roll, pitch

    def offsets(self, times: np.ndarray) -> np.ndarray:
        """(M, 3) [z m, roll rad, pitch rad] at `times` (s)."""
        tt = np.asarray(times, float)
        inside = (tt >= self.t[0]) & (tt <= self.t[-1])
        out = np.zeros((tt.size, 3))
        for k, sp in enumerate(self.splines):
            out[inside, k] = sp(tt[inside])
        return out


def stone_shake(trace_t: np.ndarray, trace_xy: np.ndarray, *, stones_per_m: float, height_m: tuple[float, float],
                length_m: float, track_m: float, wheelbase_m: float, natural_hz: float, damping: float,
                rng: np.random.Generator) -> Shake:
    """Stones at Poisson-distributed distances along the driven path (rate `stones_per_m`, 1/m),
    each under a random corner, heights uniform in `height_m` (m). A corner rolling over a stone
    rises by h (1 - cos) / 2 over `length_m` of travel, which moves the rigid body by h/4 up,
    +-h/(2 track) roll and +-h/(2 wheelbase) pitch when followed quasi-statically; the body follows
    that base motion as a damped oscillator on its tyres (natural frequency, damping ratio). So a
    machine creeping over a stone tilts slowly, and one driving fast bounces."""
    from scipy.signal import lsim

    t = np.asarray(trace_t, float)
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(trace_xy, axis=0), axis=1))]
    n = rng.poisson(stones_per_m * s[-1])
    at = np.sort(rng.uniform(0.0, s[-1], n))
    h = rng.uniform(*height_m, n)
    side, end = rng.choice([-1.0, 1.0], n), rng.choice([-1.0, 1.0], n)
    # lifting the left (+y) corner rolls the body right-side down (roll about +x positive); a front corner
    # pitches the nose up (pitch about +y negative)
    gains = np.c_[h / 4, side * h / (2 * track_m), -end * h / (2 * wheelbase_m)]
    base = np.zeros((t.size, 3))
    for sk, g in zip(at, gains, strict=True):
        u = (s - sk) / length_m
        on = (u > 0) & (u < 1)
        base[on] += 0.5 * (1.0 - np.cos(2 * np.pi * u[on]))[:, None] * g
    w = 2 * np.pi * natural_hz
    system = ([2 * damping * w, w * w], [1.0, 2 * damping * w, w * w])  # body / base transfer function
    grid = np.arange(t[0], t[-1], 5e-3)  # 200 Hz resolves the 2-3 Hz body mode
    base_grid = np.stack([np.interp(grid, t, base[:, k]) for k in range(3)], axis=1)
    response = np.stack([lsim(system, base_grid[:, k], grid - grid[0])[1] for k in range(3)], axis=1) \
        if n else np.zeros_like(base_grid)
    return Shake(grid, tuple(CubicSpline(grid, response[:, k]) for k in range(3)))


def smooth_motion(t: np.ndarray, series: np.ndarray, smoothing_s: float) -> np.ndarray:
    """`series` (N, K) sampled at the uniform stamps `t` (s), convolved with a triangle `smoothing_s`
    (s) wide (two centred moving averages of half that width). The closed-loop trace changes speed
    and yaw rate within one control step where a slip patch begins (0.04 m/s in 1 ms: 38 m/s^2 at
    the IMU, beyond its +-2 g), which no 4.8 t machine does; after smoothing a velocity step dv
    becomes an S-curve over `smoothing_s` with acceleration at most 2 dv / smoothing_s and bounded
    jerk. A triangle of width w moves a circle of radius R inwards by about w^2 / (24 R) (m)."""
    from scipy.ndimage import uniform_filter1d

    if smoothing_s <= 0 or t.size < 3:
        return np.asarray(series, float)
    dt = float(np.median(np.diff(t)))
    size = 2 * int(round(smoothing_s / 4 / dt)) + 1  # odd: centred, no half-sample shift
    out = np.asarray(series, float)
    for _ in range(2):
        out = uniform_filter1d(out, size, axis=0, mode="nearest")
    return out


@dataclass(frozen=True)
class BodyTrajectory:
    t: np.ndarray  # (N,) s, increasing
    x: np.ndarray  # (N,) m, map frame
    y: np.ndarray
    yaw: np.ndarray  # (N,) rad, unwrapped
    terrain: Terrain
    shake: Shake | None = None
    _splines: tuple[Any, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        t = np.asarray(self.t, float)
        if t.size < 4 or np.any(np.diff(t) <= 0):
            raise ValueError("the trajectory needs >= 4 strictly increasing stamps")
        # natural cubic splines through the trace: C2, so accelerations are continuous
        object.__setattr__(self, "_splines", tuple(CubicSpline(t, np.asarray(a, float), bc_type="natural")
                                                   for a in (self.x, self.y, np.unwrap(self.yaw))))

    @classmethod
    def from_trace(cls, trace, terrain: Terrain, shake: Shake | None = None,
                   smoothing_s: float = 0.0) -> BodyTrajectory:
        """From a control.closed_loop.ClosedLoopTrace (t, x, y, yaw), smoothed over `smoothing_s` (s)
        by `smooth_motion`."""
        t = np.asarray(trace.t, float)
        xy_yaw = np.c_[trace.x, trace.y, np.unwrap(np.asarray(trace.yaw, float))]
        x, y, yaw = smooth_motion(t, xy_yaw, smoothing_s).T
        return cls(t, x, y, yaw, terrain, shake)

    @property
    def start_s(self) -> float:
        return float(self.t[0])

    @property
    def end_s(self) -> float:
        return float(self.t[-1])

    def pose(self, times: np.ndarray) -> tuple[np.ndarray, Rotation]:
        """Positions (M, 3) m and orientations of base_link in the map frame at `times` (s).
        Times outside the trace hold its end points (the robot stands still)."""
        ts = np.clip(np.asarray(times, float), self.t[0], self.t[-1])
        sx, sy, syaw = self._splines
        x, y, yaw = sx(ts), sy(ts), syaw(ts)
        gx, gy = self.terrain.gradient(x, y)
        up = np.c_[-gx, -gy, np.ones_like(gx)]
        up /= np.linalg.norm(up, axis=1, keepdims=True)
        # forward = heading direction lifted onto the tangent plane, so the ZYX yaw is exactly `yaw`
        fwd = np.c_[np.cos(yaw), np.sin(yaw), gx * np.cos(yaw) + gy * np.sin(yaw)]
        fwd /= np.linalg.norm(fwd, axis=1, keepdims=True)
        left = np.cross(up, fwd)
        rot = Rotation.from_matrix(np.stack([fwd, left, up], axis=2))
        z = self.terrain.height(x, y) + BASE_HEIGHT_M
        if self.shake is None:
            return np.c_[x, y, z], rot
        d = self.shake.offsets(np.asarray(times, float))
        up_w = rot.apply([0.0, 0.0, 1.0])
        pos = np.c_[x, y, z] + d[:, :1] * up_w  # bounce along the body's up axis
        return pos, rot * Rotation.from_rotvec(np.c_[d[:, 1], d[:, 2], np.zeros(len(d))])

    def velocity(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Linear velocity (M, 3) m/s in the map frame and angular velocity (M, 3) rad/s in the body
        frame of base_link (what nav_msgs/Odometry's twist carries, linear rotated to body)."""
        h = FD_STEP_S
        p_m, r_m = self.pose(times - h)
        p_p, r_p = self.pose(times + h)
        return (p_p - p_m) / (2 * h), _body_rate(r_m, r_p, h)

    def imu_kinematics(self, times: np.ndarray, lever_arm: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, Rotation]:
        """Ideal IMU at `lever_arm` (m, base_link frame), axes of base_link: specific force (M, 3)
        m/s^2 (reaction to gravity included: +g up at rest), angular rate (M, 3) rad/s, plus the
        point's position (M, 3) and base_link orientation at `times`."""
        h = FD_STEP_S
        times = np.asarray(times, float)
        lever = np.asarray(lever_arm, float)
        p_m, r_m = self.pose(times - h)
        p_0, r_0 = self.pose(times)
        p_p, r_p = self.pose(times + h)
        q_m, q_0, q_p = p_m + r_m.apply(lever), p_0 + r_0.apply(lever), p_p + r_p.apply(lever)
        acc_w = (q_p - 2 * q_0 + q_m) / (h * h)
        specific_force = r_0.inv().apply(acc_w + np.array([0.0, 0.0, GRAVITY_MPS2]))
        return specific_force, _body_rate(r_m, r_p, h), q_0, r_0


def _body_rate(r_before: Rotation, r_after: Rotation, h: float) -> np.ndarray:
    """Body-frame angular rate (rad/s) from orientations at t - h and t + h."""
    return (r_before.inv() * r_after).as_rotvec() / (2 * h)
