"""imu_axes: whether /tf_static's mounts put the IMU's axes where the machine's turns say they are.

A ground vehicle turns about its own up axis, base_link z, on a slope as on the flat; its bumps and
sways are oscillations that net out over a couple of seconds. So the net rotation of each window of
the gyro, put into base axes through the mounts (base_link -> LiDAR -> IMU), lies along base z when
the mounts are right. An IMU whose axes are wrong in /tf_static (a frame missing, a driver in another
convention, a sensor mounted on its side) shows the turns about another axis: the run would read them
as roll or pitch (the yard circle with the IMU's axes 90 deg off: 1.85 m online APE, and the wheels
blamed). The angle between the turns' principal axis and base z says which."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mrnc_eval.slam.config import ImuAxesConfig


@dataclass(kw_only=True)
class ImuAxes:
    angle_deg: float  # between the axis the machine turned about (base axes, through the mounts) and base z
    axis: tuple[float, float, float]  # that axis (unit, base axes, sign-free)
    turned_rad: float  # net rotation of the windows that entered, rad
    verdict: str = "not measurable"  # "ok", "rotated" or "not measurable" (too little turning)
    reasons: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, object]:
        return {"angle_deg": self.angle_deg, "axis": list(self.axis), "turned_rad": self.turned_rad,
                "verdict": self.verdict, "reasons": list(self.reasons)}


def imu_axes(stamps: np.ndarray, gyro_base: np.ndarray, cfg: ImuAxesConfig) -> ImuAxes:
    """The turn axis of a gyro series (stamps (N,) s ascending; angular rate (N, 3) rad/s in base
    axes through the mounts) against base z."""
    turns = _window_rotations(np.asarray(stamps, float), np.asarray(gyro_base, float), cfg.window_s)
    turns = turns[np.linalg.norm(turns, axis=1) > cfg.min_window_rad] if turns.size else turns
    turned = float(np.linalg.norm(turns, axis=1).sum()) if turns.size else 0.0
    if turned < cfg.min_turn_rad:
        return ImuAxes(angle_deg=float("nan"), axis=(float("nan"),) * 3, turned_rad=turned,
                       reasons=[f"{turned:.2f} rad of turning in {cfg.window_s:g} s windows: too little"])
    _, vectors = np.linalg.eigh(turns.T @ turns)
    axis = vectors[:, -1] * (1.0 if vectors[2, -1] >= 0 else -1.0)
    angle = float(np.degrees(np.arccos(np.clip(abs(axis[2]), 0.0, 1.0))))
    out = ImuAxes(angle_deg=angle, axis=(float(axis[0]), float(axis[1]), float(axis[2])), turned_rad=turned,
                  verdict="ok")
    if angle > cfg.max_angle_deg:
        out.verdict = "rotated"
        out.reasons = [f"the machine turned about an axis {angle:.0f} deg from base_link z in the IMU's axes "
                       f"(base axes: {axis[0]:+.2f}, {axis[1]:+.2f}, {axis[2]:+.2f})"]
    return out


def _window_rotations(t: np.ndarray, w: np.ndarray, window_s: float) -> np.ndarray:
    """The net rotation vector (rad, small-angle sum) of each window_s-long window of samples."""
    if t.size < 2:
        return np.zeros((0, 3))
    dt = np.diff(t, append=t[-1])
    index = ((t - t[0]) // window_s).astype(int)
    out = np.zeros((int(index[-1]) + 1, 3))
    np.add.at(out, index, w * dt[:, None])
    return out
