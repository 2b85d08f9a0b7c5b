"""Ouster OS0 sweep by ray casting: each column is cast from the sensor pose at its own time
(motion distortion is real), points are expressed in the sensor frame at that time, and the
organised H x W arrays are laid out as ouster-ros publishes them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrnc_eval.sim.config import LidarSimConfig
from mrnc_eval.sim.motion import BodyMotion


@dataclass(frozen=True)
class OrganisedSweep:
    stamp: float
    xyz: np.ndarray  # (H, W, 3) float32, sensor frame, zeros for no return
    t_ns: np.ndarray  # (H, W) uint32, ns since stamp
    range_mm: np.ndarray
    reflectivity: np.ndarray
    intensity: np.ndarray
    ambient: np.ndarray


def beam_directions(cfg: LidarSimConfig) -> np.ndarray:
    """(H, W, 3) unit directions in the sensor frame. Ring 0 is the top beam; column 0 looks
    backwards and the azimuth decreases with the column (the sensor spins clockwise)."""
    half = np.radians(cfg.vertical_fov_deg) / 2
    el = np.linspace(half, -half, cfg.beams)
    az = np.pi - 2 * np.pi * np.arange(cfg.columns) / cfg.columns
    ce = np.cos(el)[:, None]
    return np.stack([ce * np.cos(az)[None], ce * np.sin(az)[None], np.repeat(np.sin(el)[:, None], cfg.columns, 1)],
                    axis=2)


class LidarSimulator:
    def __init__(self, scene, cfg: LidarSimConfig, base_to_sensor: np.ndarray, rng: np.random.Generator) -> None:
        import open3d as o3d

        self.o3d = o3d
        self.rs = scene.raycasting_scene()
        self.refl = np.asarray(scene.reflectivity + [0.0], np.float32)
        self.cfg = cfg
        self.dirs = beam_directions(cfg)
        self.base_to_sensor = base_to_sensor
        self.rng = rng
        self.col_dt = 1.0 / (cfg.rate_hz * cfg.columns)

    def sweep(self, motion: BodyMotion, stamp: float) -> OrganisedSweep:
        c = self.cfg
        col_t = stamp + np.arange(c.columns) * self.col_dt
        p, r = motion.pose(col_t)
        rot_ws = r.as_matrix() @ self.base_to_sensor[:3, :3]  # (W, 3, 3)
        origin = p + r.apply(self.base_to_sensor[:3, 3])  # (W, 3)
        d_world = np.einsum("wij,hwj->hwi", rot_ws, self.dirs)
        rays = np.concatenate([np.broadcast_to(origin[None], d_world.shape), d_world], axis=2).reshape(-1, 6)
        hit = self.rs.cast_rays(self.o3d.core.Tensor(rays.astype(np.float32)))
        rng_m = hit["t_hit"].numpy().reshape(c.beams, c.columns).astype(np.float64)
        gid = hit["geometry_ids"].numpy().reshape(c.beams, c.columns)
        rng_m = rng_m + self.rng.normal(0.0, c.range_noise_m, rng_m.shape)
        valid = np.isfinite(rng_m) & (rng_m <= c.max_range_m) & (rng_m >= c.min_range_m)
        rng_m = np.where(valid, rng_m, 0.0)
        xyz = (self.dirs * rng_m[..., None]).astype(np.float32)
        gid = np.where(valid, np.minimum(gid, len(self.refl) - 1), len(self.refl) - 1)
        refl = (self.refl[gid] * 255).astype(np.uint16)
        intensity = np.where(valid, refl * 40.0 / np.maximum(rng_m, 1.0), 0.0).astype(np.float32)
        ambient = self.rng.integers(0, 40, rng_m.shape).astype(np.uint16)
        t_ns = np.broadcast_to((np.arange(c.columns) * self.col_dt * 1e9).astype(np.uint32), rng_m.shape)
        return OrganisedSweep(stamp, xyz, np.ascontiguousarray(t_ns), (rng_m * 1000).astype(np.uint32), refl,
                              intensity, ambient)
