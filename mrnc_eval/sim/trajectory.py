"""Ground-truth body motion: the closed-loop trace (x, y, yaw at the control rate) as cubic
splines, lifted onto the terrain. z follows the heightfield and the body's up axis is the exact
terrain normal, so pitch and roll follow the ground. Every quantity is a smooth function of
time, so IMU derivatives and LiDAR per-column poses agree with the ground truth. An optional
`Shake` adds the body's bounce, roll and pitch after its wheels roll over stones (field profile)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from mrnc_eval.sim.scene import Terrain

BASE_HEIGHT_M = 0.6  # base_link above the ground contact, along the terrain normal's vertical
GRAVITY_MPS2 = 9.80665  # standard gravity, m/s^2 (world z up)
FD_STEP_S = 1e-3  # central-difference step on the splines, s


@dataclass(frozen=True)
class Shake:
    """Body oscillations excited by stones under single wheels: event k at time t_k (s) lifts one
    corner by h_k, which moves the rigid body by (h/4 up, +-h/(2 track) roll, +-h/(2 wheelbase)
    pitch) quasi-statically; the body answers as a damped oscillator on its tyres (natural
    frequency f, damping ratio zeta). The response shape rises smoothly (C2) over ~0.05 s."""

    times: np.ndarray  # (K,) s
    amplitudes: np.ndarray  # (K, 3) [z m, roll rad, pitch rad]
    natural_hz: float
    damping: float

    RISE_S = 0.03  # time constant of the smooth onset, s
    SETTLE_S = 4.0  # responses are cut after this (e^-4 at the default damping), s

    def offsets(self, times: np.ndarray) -> np.ndarray:
        """(M, 3) [z m, roll rad, pitch rad] at `times` (s)."""
        t = np.asarray(times, float)
        out = np.zeros((t.size, 3))
        w = 2 * np.pi * self.natural_hz
        wd = w * np.sqrt(max(1.0 - self.damping ** 2, 1e-6))
        for tk, amp in zip(self.times, self.amplitudes, strict=True):
            lo, hi = np.searchsorted(t, (tk, tk + self.SETTLE_S)) if _is_sorted(t) else (0, t.size)
            tau = t[lo:hi] - tk
            tau = np.maximum(tau, 0.0)
            g = np.exp(-self.damping * w * tau) * np.sin(wd * tau) * (1.0 - np.exp(-tau / self.RISE_S)) ** 2
            out[lo:hi] += g[:, None] * amp
        return out


def _is_sorted(t: np.ndarray) -> bool:
    return t.size < 2 or bool(np.all(np.diff(t) >= 0))


def stone_shake(trace_t: np.ndarray, trace_xy: np.ndarray, *, stones_per_m: float, height_m: tuple[float, float],
                track_m: float, wheelbase_m: float, natural_hz: float, damping: float,
                rng: np.random.Generator) -> Shake:
    """Stones at Poisson-distributed distances along the driven path (rate `stones_per_m`, 1/m),
    each under a random corner, with heights uniform in `height_m` (m)."""
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(trace_xy, axis=0), axis=1))]
    n = rng.poisson(stones_per_m * s[-1])
    at = np.sort(rng.uniform(0.0, s[-1], n))
    times = np.interp(at, s, trace_t)
    h = rng.uniform(*height_m, n)
    side, end = rng.choice([-1.0, 1.0], n), rng.choice([-1.0, 1.0], n)
    # lifting the left (+y) corner rolls the body right-side down: roll about +x is positive
    amps = np.c_[h / 4, side * h / (2 * track_m), -end * h / (2 * wheelbase_m)]
    return Shake(times, amps, natural_hz, damping)


@dataclass(frozen=True)
class BodyTrajectory:
    t: np.ndarray  # (N,) s, increasing
    x: np.ndarray  # (N,) m, map frame
    y: np.ndarray
    yaw: np.ndarray  # (N,) rad, unwrapped
    terrain: Terrain
    shake: Shake | None = None
    _splines: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        t = np.asarray(self.t, float)
        if t.size < 4 or np.any(np.diff(t) <= 0):
            raise ValueError("the trajectory needs >= 4 strictly increasing stamps")
        # natural cubic splines through the trace: C2, so accelerations are continuous
        object.__setattr__(self, "_splines", tuple(CubicSpline(t, np.asarray(a, float), bc_type="natural")
                                                   for a in (self.x, self.y, np.unwrap(self.yaw))))

    @classmethod
    def from_trace(cls, trace, terrain: Terrain, shake: Shake | None = None) -> BodyTrajectory:
        """From a control.closed_loop.ClosedLoopTrace (t, x, y, yaw)."""
        return cls(np.asarray(trace.t, float), np.asarray(trace.x, float), np.asarray(trace.y, float),
                   np.unwrap(np.asarray(trace.yaw, float)), terrain, shake)

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
