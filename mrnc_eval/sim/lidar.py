"""Ouster OS0 sweep by ray casting (open3d RaycastingScene, one batch per sweep).

Geometry follows the Ouster sensor model: column j fires at encoder angle 2 pi (1 - j / W) in the
os_lidar frame (rotated 180 deg about z from os_sensor, so column 0 looks backwards), each ring
has its altitude and a small azimuth offset (staggered columns, as ouster-ros publishes them),
rays start at the beam origin `n` off the axis and range = n + distance. Each column is cast from
the sensor pose at its own time (motion distortion is real) and its points are expressed in
os_sensor at that time. Ranges are quantised to mm and xyz derived from them, like the driver.

Returns: detection needs albedo * cos(incidence) / r^2 above what a 10 % target gives at the
detection range; intensity is the photon signal (Poisson); reflectivity is the calibrated
0-100 % Lambertian scale (falls at grazing incidence); ambient is sunlight NIR (Poisson).
With a `FieldLidar` (field profile) a moving object is cast per column and the returns get the
range-, reflectivity- and incidence-dependent noise, mixed pixels, outliers and dropouts of
sim/lidar_field.py; without one, every draw is the ideal model's (byte-identical logs)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from mrnc_eval.sim.config import FieldLidarConfig, LidarSimConfig
from mrnc_eval.sim.lidar_field import MovingBox, Puddles, dark_dropout, mixed_pixels, outliers, range_sigma
from mrnc_eval.sim.trajectory import BodyTrajectory

SIGNAL_AT_DETECTION_LIMIT = 30.0  # photon signal of the weakest detected return
MAX_U16 = 65535


@dataclass(frozen=True)
class OrganisedSweep:
    stamp: float  # s, time of column 0 (header stamp)
    xyz: np.ndarray  # (H, W, 3) float32, os_sensor at each column's time, zeros for no return
    t_ns: np.ndarray  # (H, W) uint32, ns since stamp
    range_mm: np.ndarray  # (H, W) uint32
    reflectivity: np.ndarray  # (H, W) uint16
    intensity: np.ndarray  # (H, W) float32
    ambient: np.ndarray  # (H, W) uint16


@dataclass(frozen=True)
class BeamModel:
    """Per-pixel ray geometry in os_sensor (constant over sweeps)."""

    altitude_deg: np.ndarray  # (H,) ring 0 = top beam
    azimuth_offset_deg: np.ndarray  # (H,)
    origins: np.ndarray  # (W, 3) m, beam origin of each column
    directions: np.ndarray  # (H, W, 3) unit
    beam_offset_m: float


def beam_model(cfg: LidarSimConfig) -> BeamModel:
    half = cfg.vertical_fov_deg / 2
    altitude = np.linspace(half, -half, cfg.beams)
    pattern = np.asarray(cfg.beam_azimuth_offsets_deg or (0.0,), float)
    az_off = pattern[np.arange(cfg.beams) % pattern.size]
    enc = 2 * np.pi * (1.0 - np.arange(cfg.columns) / cfg.columns)  # encoder angle, os_lidar
    n = cfg.lidar_origin_to_beam_origin_mm / 1000.0
    phi = np.radians(altitude)[:, None]
    theta = enc[None, :] - np.radians(az_off)[:, None]
    # os_lidar -> os_sensor: rotation of pi about z (x, y negated), then up by lidar_to_sensor_z_m
    dirs = np.stack([-np.cos(theta) * np.cos(phi), -np.sin(theta) * np.cos(phi),
                     np.broadcast_to(np.sin(phi), theta.shape)], axis=2)
    origins = np.c_[-n * np.cos(enc), -n * np.sin(enc), np.full(enc.size, cfg.lidar_to_sensor_z_m)]
    return BeamModel(altitude, az_off, origins, dirs, n)


def beam_directions(cfg: LidarSimConfig) -> np.ndarray:
    """(H, W, 3) unit ray directions in os_sensor."""
    return beam_model(cfg).directions


@dataclass(frozen=True)
class BodyBox:
    """The robot's body as a box in base_link (m): it moves with the sensor, so what it blocks is a
    fixed set of pixels at fixed ranges."""

    centre: tuple[float, float, float]
    size: tuple[float, float, float]
    albedo: float = 0.3  # painted steel


def _body_hits(body: BodyBox, base_to_sensor: np.ndarray, bm: BeamModel) -> tuple[np.ndarray, np.ndarray]:
    """Distance along each ray to the body (inf where it misses) and |cos| of the incidence."""
    import open3d as o3d

    from mrnc_eval.sim.scene import box_mesh

    cx, cy, cz = body.centre
    v, t = box_mesh(cx, cy, cz - body.size[2] / 2, *body.size)
    sensor_to_base = np.linalg.inv(base_to_sensor)
    v_s = v @ sensor_to_base[:3, :3].T + sensor_to_base[:3, 3]
    rs = o3d.t.geometry.RaycastingScene()
    rs.add_triangles(o3d.core.Tensor(v_s.astype(np.float32)), o3d.core.Tensor(t.astype(np.uint32)))
    rays = np.concatenate([np.broadcast_to(bm.origins[None], bm.directions.shape), bm.directions], axis=2)
    hit = rs.cast_rays(o3d.core.Tensor(np.ascontiguousarray(rays, np.float32).reshape(-1, 6)))
    h, w = bm.directions.shape[:2]
    dist = hit["t_hit"].numpy().reshape(h, w).astype(np.float64)
    normal = hit["primitive_normals"].numpy().reshape(h, w, 3).astype(np.float64)
    return dist, np.abs((normal * bm.directions).sum(axis=2))


@dataclass(frozen=True)
class FieldLidar:
    """Field-profile additions: the return model, puddles on the ground, a moving object and a
    generator of their own (so the ideal draws are untouched)."""

    cfg: FieldLidarConfig
    puddles: Puddles
    moving: MovingBox | None
    rng: np.random.Generator


class LidarSimulator:
    def __init__(self, scene, cfg: LidarSimConfig, base_to_sensor: np.ndarray, rng: np.random.Generator,
                 body: BodyBox | None = None, field: FieldLidar | None = None) -> None:
        import open3d as o3d

        self._o3d = o3d
        self._rs = scene.raycasting_scene()
        self._albedo = np.asarray(list(scene.reflectivity) + [0.0], np.float64)  # last = nothing hit
        self.cfg = cfg
        self.beams = beam_model(cfg)
        self._dirs_whj = np.ascontiguousarray(self.beams.directions.transpose(1, 0, 2))  # (W, H, 3)
        self.base_to_sensor = base_to_sensor
        self.rng = rng
        self.col_dt = 1.0 / (cfg.rate_hz * cfg.columns)
        self._t_ns = np.ascontiguousarray(np.broadcast_to(
            np.round(np.arange(cfg.columns) * self.col_dt * 1e9).astype(np.uint32), (cfg.beams, cfg.columns)))
        el = math.radians(cfg.sun_elevation_deg)
        sun_az = rng.uniform(0.0, 2 * np.pi)
        self._sun = np.array([math.cos(el) * math.cos(sun_az), math.cos(el) * math.sin(sun_az), math.sin(el)])
        # weakest detectable albedo * cos / r^2 (10 % target, normal incidence, at the detection range)
        self._min_return = 0.1 / cfg.detect_range_10pct_m ** 2
        self._body = None if body is None else (*_body_hits(body, base_to_sensor, self.beams), body.albedo)
        self.field = field
        self._terrain = scene.terrain
        self._moving_rs = None
        if field is not None and field.moving is not None:
            from mrnc_eval.sim.scene import box_mesh

            sx, sy, sz = field.moving.size
            v, t = box_mesh(0.0, 0.0, 0.0, sx, sy, sz)
            self._moving_rs = o3d.t.geometry.RaycastingScene()
            self._moving_rs.add_triangles(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(t.astype(np.uint32)))

    def sweep(self, traj: BodyTrajectory, stamp: float) -> OrganisedSweep:
        c, bm = self.cfg, self.beams
        low_bandwidth = c.packet_profile == "RNG15_RFL8_NIR8"
        col_t = stamp + np.arange(c.columns) * self.col_dt
        p, r = traj.pose(col_t)
        rot_ws = r.as_matrix() @ self.base_to_sensor[:3, :3]  # (W, 3, 3) os_sensor in map
        sensor_w = p + r.apply(self.base_to_sensor[:3, 3])
        origin_w = sensor_w + np.matmul(rot_ws, bm.origins[..., None])[..., 0]
        d_world = np.matmul(self._dirs_whj, rot_ws.transpose(0, 2, 1)).transpose(1, 0, 2)  # (H, W, 3)
        rays = np.concatenate([np.broadcast_to(origin_w[None], d_world.shape), d_world], axis=2)
        hit = self._rs.cast_rays(self._o3d.core.Tensor(np.ascontiguousarray(rays, np.float32).reshape(-1, 6)))
        dist = hit["t_hit"].numpy().reshape(c.beams, c.columns).astype(np.float64)
        gid = hit["geometry_ids"].numpy().reshape(c.beams, c.columns)
        normal = hit["primitive_normals"].numpy().reshape(c.beams, c.columns, 3).astype(np.float64)
        found = np.isfinite(dist)
        gid = np.where(found, np.minimum(gid, self._albedo.size - 1), self._albedo.size - 1)
        albedo = self._albedo[gid]
        cos_inc = np.abs((normal * d_world).sum(axis=2))
        if self.field is not None:
            dist, cos_inc, found, albedo = self._field_world(col_t, origin_w, d_world, dist, gid, cos_inc, found,
                                                             albedo)
        if self._body is not None:  # the robot's own body is in front of the world for these pixels
            body_dist, body_cos, body_albedo = self._body
            own = body_dist < np.where(found, dist, np.inf)
            dist, cos_inc, found = np.where(own, body_dist, dist), np.where(own, body_cos, cos_inc), found | own
            albedo = np.where(own, body_albedo, albedo)
        safe = np.where(found, np.maximum(dist + bm.beam_offset_m, 0.1), 1.0)
        strength = albedo * cos_inc / safe ** 2
        if self.field is None:
            rng_m = safe + self.rng.normal(0.0, c.range_noise_m, dist.shape)
            detected = found & (strength >= self._min_return)
        else:
            rng_m, detected = self._field_ranges(safe, found, albedo, cos_inc, strength)
        valid = detected & (rng_m <= c.max_range_m) & (rng_m >= c.min_range_m)
        step_mm = 8.0 if low_bandwidth else 1.0
        range_mm = np.where(valid, np.round(rng_m * 1000.0 / step_mm) * step_mm, 0.0).astype(np.uint32)
        along = np.where(valid, range_mm / 1000.0 - bm.beam_offset_m, 0.0)
        xyz = np.where(valid[..., None], bm.origins[None] + bm.directions * along[..., None], 0.0).astype(np.float32)
        intensity, refl, ambient = self._channels(valid, found, strength, albedo, cos_inc, normal, d_world)
        if low_bandwidth:  # no signal channel: ouster-ros fills intensity with reflectivity; NIR has 8 bits
            intensity = refl.astype(np.float32)
            ambient = np.minimum(ambient // 16, 255) * 16
        return OrganisedSweep(stamp, xyz, self._t_ns, range_mm, refl, intensity, ambient.astype(np.uint16))

    def _channels(self, valid: np.ndarray, found: np.ndarray, strength: np.ndarray, albedo: np.ndarray,
                  cos_inc: np.ndarray, normal: np.ndarray, d_world: np.ndarray,
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Signal (photons, as intensity), reflectivity (0-255) and ambient (NIR photons) per pixel,
        drawn in this order."""
        c = self.cfg
        signal = self.rng.poisson(np.where(valid, SIGNAL_AT_DETECTION_LIMIT * strength / self._min_return, 0.0))
        intensity = np.minimum(signal, MAX_U16).astype(np.float32)
        refl = np.where(valid, np.round(100.0 * albedo * np.sqrt(cos_inc) + self.rng.normal(0.0, 1.0, valid.shape)),
                        0)
        sunlit = np.clip(normal @ self._sun, 0.0, 1.0)
        looking_up = d_world[..., 2] > 0
        ambient_mean = np.where(found, c.ambient_sunlit_photons * (0.05 + albedo * sunlit),
                                np.where(looking_up, c.ambient_sky_photons, 0.0))
        ambient = np.minimum(self.rng.poisson(ambient_mean), MAX_U16)
        return intensity, np.clip(refl, 0, 255).astype(np.uint16), ambient


    def _field_world(self, col_t, origin_w, d_world, dist, gid, cos_inc, found, albedo):
        """Puddles darken the ground (geometry 0); the moving object is in front where it is hit."""
        f = self.field
        assert f is not None
        ground = found & (gid == 0)
        if ground.any() and len(f.puddles.radii):
            hit_xy = (origin_w[None, :, :2] + d_world[..., :2] * np.where(found, dist, 0.0)[..., None])[ground]
            wet = np.zeros_like(ground)
            wet[ground] = f.puddles.contains(hit_xy)
            albedo = np.where(wet, f.cfg.wet_albedo, albedo)
        if self._moving_rs is None or f.moving is None:
            return dist, cos_inc, found, albedo
        m = f.moving
        centre = m.centre_xy(col_t)  # (W, 2)
        rel = centre - origin_w[:, :2]
        reach = np.hypot(*m.size[:2]) / 2 + 0.5
        span = np.arctan2(reach, np.maximum(np.linalg.norm(rel, axis=1), 1e-3))
        mid = d_world[d_world.shape[0] // 2]
        off = np.angle(np.exp(1j * (np.arctan2(mid[:, 1], mid[:, 0]) - np.arctan2(rel[:, 1], rel[:, 0]))))
        cols = np.flatnonzero((np.abs(off) < span + 0.05) & (np.linalg.norm(rel, axis=1) < self.cfg.max_range_m))
        if cols.size == 0:
            return dist, cos_inc, found, albedo
        yaw = math.atan2(m.direction[1], m.direction[0])
        rot = np.array([[math.cos(yaw), -math.sin(yaw), 0.0], [math.sin(yaw), math.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
        base = np.c_[centre[cols], self._terrain.height(centre[cols, 0], centre[cols, 1])]  # (C, 3)
        o_local = (origin_w[cols] - base) @ rot  # R^T (o - c)
        d_local = d_world[:, cols] @ rot
        rays = np.concatenate([np.broadcast_to(o_local[None], d_local.shape), d_local], axis=2)
        hit = self._moving_rs.cast_rays(self._o3d.core.Tensor(np.ascontiguousarray(rays, np.float32).reshape(-1, 6)))
        h = d_world.shape[0]
        t_obj = hit["t_hit"].numpy().reshape(h, cols.size).astype(np.float64)
        n_obj = hit["primitive_normals"].numpy().reshape(h, cols.size, 3).astype(np.float64)
        sub = np.where(found[:, cols], dist[:, cols], np.inf)
        own = t_obj < sub
        dist, cos_inc, found, albedo = dist.copy(), cos_inc.copy(), found.copy(), albedo.copy()
        dist[:, cols] = np.where(own, t_obj, dist[:, cols])
        cos_inc[:, cols] = np.where(own, np.abs((n_obj * d_local).sum(axis=2)), cos_inc[:, cols])
        found[:, cols] |= own
        albedo[:, cols] = np.where(own, m.albedo, albedo[:, cols])
        return dist, cos_inc, found, albedo

    def _field_ranges(self, safe, found, albedo, cos_inc, strength):
        """Measured ranges (m) and the detection mask of the field return model."""
        f = self.field
        assert f is not None
        c = self.cfg
        true_range = np.where(found, safe, np.inf)
        mixed, _ = mixed_pixels(np.where(found, safe, 0.0), found, c.columns, f.cfg, f.rng)
        sigma = range_sigma(mixed, albedo, cos_inc, f.cfg)
        rng_m = np.where(found, mixed, safe) + self.rng.normal(0.0, 1.0, safe.shape) * sigma
        detected = found & (strength >= self._min_return) & dark_dropout(albedo * cos_inc, f.cfg, f.rng)
        rng_m, _ = outliers(rng_m, detected & np.isfinite(true_range), c.min_range_m, f.cfg, f.rng)
        return rng_m, detected


def ouster_metadata(cfg: LidarSimConfig, sensor_to_imu: np.ndarray, model: str) -> str:
    """The sensor metadata JSON ouster-ros publishes on /ouster/metadata (fields of the real one)."""
    bm = beam_model(cfg)
    shift = np.round((bm.azimuth_offset_deg - bm.azimuth_offset_deg.min()) * cfg.columns / 360.0).astype(int)
    imu_mm = sensor_to_imu.copy()
    imu_mm[:3, 3] *= 1000.0
    lidar_to_sensor = np.diag([-1.0, -1.0, 1.0, 1.0])
    lidar_to_sensor[2, 3] = cfg.lidar_to_sensor_z_m * 1000.0
    return json.dumps({
        "prod_line": f"OS-0-{cfg.beams}", "prod_pn": "simulated", "prod_sn": "0", "build_rev": "mrnc-eval-sim",
        "status": "RUNNING", "lidar_mode": f"{cfg.columns}x{int(cfg.rate_hz)}",
        "beam_altitude_angles": [round(float(a), 4) for a in bm.altitude_deg],
        "beam_azimuth_angles": [round(float(a), 4) for a in bm.azimuth_offset_deg],
        "lidar_origin_to_beam_origin_mm": cfg.lidar_origin_to_beam_origin_mm,
        "lidar_to_sensor_transform": [round(float(v), 6) for v in lidar_to_sensor.ravel()],
        "imu_to_sensor_transform": [round(float(v), 6) for v in imu_mm.ravel()],
        "data_format": {"columns_per_frame": cfg.columns, "columns_per_packet": 16, "pixels_per_column": cfg.beams,
                        "column_window": [0, cfg.columns - 1], "pixel_shift_by_row": [int(s) for s in shift],
                        "udp_profile_lidar": cfg.packet_profile, "udp_profile_imu": "LEGACY"},
    }, sort_keys=True)
