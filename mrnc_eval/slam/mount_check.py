"""mount_check: the LiDAR mount's pitch and yaw error seen from the robot's own motion.

A ground vehicle moves along its base x axis: it does not climb through its own floor and, at a low
yaw rate, a skid-steer barely side-slips. The base poses come from the LiDAR's poses through the
/tf_static mount, so a mount rotated by a small angle w (true relative to written, base axes) shows
the motion in the estimated base frame at an elevation of w_y (pitch) and a lateral angle of -w_z
(yaw); roll leaves the x axis in place and cannot be seen. Over the moving, nearly straight stretches
of the final trajectory the summed base-frame displacement gives both angles; their standard errors
come from a delete-one-block jackknife over time blocks (neighbouring samples share poses).

The base_link poses (and so an origin-aligned end drift) carry the error: 0.4 deg of pitch tilts a
40 m line by 0.28 m of z."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mrnc_eval.geometry import rotation
from mrnc_eval.slam.config import MountCheckConfig


@dataclass(kw_only=True)
class MountCheck:
    pitch_deg: float  # mount pitch error (true relative to written, base axes): the motion's elevation, deg
    pitch_sigma_deg: float  # jackknife standard error, deg
    yaw_deg: float  # mount yaw error (base axes): minus the motion's lateral angle, deg
    yaw_sigma_deg: float
    samples: int  # motion samples used (moving, yaw rate below the limit)
    distance_m: float  # distance driven over them, m
    # rotation to right-multiply the written mount's rotation by (roll, pitch, yaw, fixed axes, LiDAR
    # axes, deg): the correction that removes the error found; roll is not observable and stays 0
    correction_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    verdict: str = "insufficient"  # "ok", "misaligned" or "insufficient" (too little straight motion)
    flagged: tuple[str, ...] = ()  # the angles beyond the flag ("pitch", "yaw")
    reasons: list[str] = field(default_factory=list)

    def flagged_sigma_deg(self) -> float:
        """The largest standard error among the flagged angles, deg (0 when none is)."""
        sigma = {"pitch": self.pitch_sigma_deg, "yaw": self.yaw_sigma_deg}
        return max((sigma[a] for a in self.flagged), default=0.0)

    def as_dict(self) -> dict[str, object]:
        return {"pitch_deg": self.pitch_deg, "pitch_sigma_deg": self.pitch_sigma_deg, "yaw_deg": self.yaw_deg,
                "yaw_sigma_deg": self.yaw_sigma_deg, "samples": self.samples, "distance_m": self.distance_m,
                "correction_rpy_deg": list(self.correction_rpy_deg), "verdict": self.verdict,
                "reasons": list(self.reasons)}


def mount_check(stamps: np.ndarray, base_poses: np.ndarray, mount_rotation: np.ndarray,
                cfg: MountCheckConfig) -> MountCheck:
    """The mount's pitch and yaw error from base poses (N, 4, 4, map frame, stamps in s, any order);
    `mount_rotation`: the written base_link -> LiDAR rotation (3x3), to express the correction in
    LiDAR axes."""
    order = np.argsort(stamps, kind="stable")  # searchsorted's order (a trajectory is; a caller's may not be)
    u, dist = motion_samples(np.asarray(stamps, float)[order], np.asarray(base_poses, float)[order], cfg)
    if u.shape[0] < max(cfg.min_samples, 2 * cfg.blocks) or dist < cfg.min_distance_m:
        return MountCheck(pitch_deg=float("nan"), pitch_sigma_deg=float("nan"), yaw_deg=float("nan"),
                          yaw_sigma_deg=float("nan"), samples=int(u.shape[0]), distance_m=dist,
                          reasons=[f"{u.shape[0]} samples over {dist:.1f} m of straight motion: too few"])
    angles = _angles(u.sum(axis=0))
    sigma = _jackknife(u, cfg.blocks)
    out = MountCheck(pitch_deg=float(angles[0]), pitch_sigma_deg=float(sigma[0]), yaw_deg=float(angles[1]),
                     yaw_sigma_deg=float(sigma[1]), samples=int(u.shape[0]), distance_m=dist, verdict="ok")
    flagged = [_off(a, s, cfg) for a, s in zip(angles, sigma, strict=True)]
    out.reasons = [f"{name} {a:+.2f} +- {s:.2f} deg" for name, a, s, f
                   in zip(("pitch", "yaw"), angles, sigma, flagged, strict=True) if f]
    out.flagged = tuple(name for name, f in zip(("pitch", "yaw"), flagged, strict=True) if f)
    out.verdict = "misaligned" if out.reasons else "ok"
    # only the flagged angles enter the correction, turned from base into LiDAR axes
    w_base = np.radians([0.0, angles[0] * flagged[0], angles[1] * flagged[1]])
    corr = np.degrees(rotation.rpy(rotation.exp(np.asarray(mount_rotation, float).T @ w_base))) + 0.0  # no -0.0
    out.correction_rpy_deg = (float(corr[0]), float(corr[1]), float(corr[2]))
    return out


def motion_samples(stamps: np.ndarray, poses: np.ndarray, cfg: MountCheckConfig) -> tuple[np.ndarray, float]:
    """Per pose, the chord from span_s/2 before to span_s/2 after it in the pose's own base axes (the
    chord of a constant-curvature arc is along the heading at its middle), kept where the speed is
    above min_speed_mps and the yaw rate below max_yaw_rate_rad_s; flipped forward when reversing.
    `stamps` ascending. Returns the (M, 3) chords (m) and the distance driven over the poses kept (m)."""
    if stamps.size < 3:
        return np.zeros((0, 3)), 0.0
    half = 0.5 * cfg.span_s
    j = np.searchsorted(stamps, stamps - half, side="left")
    k = np.searchsorted(stamps, stamps + half, side="right") - 1
    ok = (k > j) & (stamps - stamps[j] > 0.4 * half) & (stamps[k] - stamps > 0.4 * half)
    i, j, k = np.flatnonzero(ok), j[ok], k[ok]
    dt = stamps[k] - stamps[j]
    chord = np.einsum("nji,nj->ni", poses[i, :3, :3], poses[k, :3, 3] - poses[j, :3, 3])
    rel = np.einsum("nji,njk->nik", poses[j, :3, :3], poses[k, :3, :3])
    yaw_rate = rotation.log(rel)[:, 2] / dt
    speed = np.linalg.norm(chord, axis=1) / dt
    keep = (speed > cfg.min_speed_mps) & (np.abs(yaw_rate) < cfg.max_yaw_rate_rad_s)
    u = chord[keep] * np.where(chord[keep, 0] < 0.0, -1.0, 1.0)[:, None]
    driven = speed[keep] * np.gradient(stamps)[i[keep]]  # each pose's share of the distance, m
    return u, float(driven.sum())


def _angles(s: np.ndarray) -> np.ndarray:
    """(pitch, yaw) error, deg, from a summed base-frame displacement: elevation and minus the lateral angle."""
    return np.degrees([np.arctan2(s[2], s[0]), -np.arctan2(s[1], s[0])])


def _jackknife(u: np.ndarray, blocks: int) -> np.ndarray:
    """Delete-one-block jackknife standard error of _angles over `blocks` contiguous time blocks, deg."""
    parts = np.array_split(np.arange(u.shape[0]), blocks)
    total = u.sum(axis=0)
    est = np.array([_angles(total - u[p].sum(axis=0)) for p in parts])
    n = len(parts)
    spread: np.ndarray = np.sum((est - est.mean(axis=0)) ** 2, axis=0)
    return np.sqrt((n - 1) / n * spread)


def _off(value: float, sigma: float, cfg: MountCheckConfig) -> bool:
    """An angle beyond flag_deg and beyond flag_sigmas standard errors (deg)."""
    return bool(abs(value) > cfg.flag_deg and abs(value) > cfg.flag_sigmas * sigma)
