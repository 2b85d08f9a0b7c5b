"""Field-profile LiDAR returns: what thin, exact rays leave out. Pure functions on the sweep's
(H, W) arrays plus the one moving object of the scene.

- range noise sigma = floor (+) ref * (r / ref_range) * sqrt(0.1 / reflectivity) (+) the beam
  footprint's spread on an inclined surface, r * tan(divergence / 2) * tan(incidence) / sqrt(3);
  (+) adds in quadrature. The middle term is 1 / sqrt(SNR) with SNR ~ reflectivity / r^2.
- mixed pixels: at a depth edge between neighbouring columns the footprint straddles both
  surfaces with probability divergence / column spacing; the return then lies between them.
- outliers: a fraction of returns at a uniform random range short of the true one.
- dark and wet surfaces: returns weaker than `dark_albedo` drop out proportionally; puddles on
  the ground have the albedo of water."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mrnc_eval.sim.config import FieldLidarConfig


def range_sigma(range_m: np.ndarray, albedo: np.ndarray, cos_inc: np.ndarray, cfg: FieldLidarConfig) -> np.ndarray:
    """(H, W) 1-sigma range noise, m."""
    snr_term = cfg.range_noise_ref_m * (range_m / cfg.range_noise_ref_range_m) * np.sqrt(
        0.1 / np.maximum(albedo * np.sqrt(np.clip(cos_inc, 0.0, 1.0)), 0.01))
    tan_inc = np.sqrt(np.maximum(1.0 - cos_inc ** 2, 0.0)) / np.maximum(cos_inc, 0.1)
    footprint = range_m * math.tan(math.radians(cfg.beam_divergence_deg) / 2) * tan_inc / math.sqrt(3.0)
    return np.sqrt(cfg.range_noise_floor_m ** 2 + snr_term ** 2 + footprint ** 2)


def mixed_pixels(range_m: np.ndarray, found: np.ndarray, columns: int, cfg: FieldLidarConfig,
                 rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Ranges with mixed pixels at depth edges (neighbouring columns of a ring, wrapping) and the
    mask of pixels that were mixed."""
    spacing = 360.0 / columns
    p_mix = min(1.0, cfg.beam_divergence_deg / spacing)
    nxt = np.roll(range_m, -1, axis=1)
    both = found & np.roll(found, -1, axis=1)
    edge = both & (np.abs(nxt - range_m) > cfg.mixed_pixel_jump_m)
    mixed = edge & (rng.random(range_m.shape) < p_mix)
    u = rng.random(range_m.shape)
    return np.where(mixed, range_m + u * (nxt - range_m), range_m), mixed


def outliers(range_m: np.ndarray, valid: np.ndarray, min_range_m: float, cfg: FieldLidarConfig,
             rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A fraction of valid returns moved to a uniform range in [min_range, true range)."""
    out = valid & (rng.random(range_m.shape) < cfg.outlier_fraction)
    short = min_range_m + rng.random(range_m.shape) * np.maximum(range_m - min_range_m, 0.0)
    return np.where(out, short, range_m), out


def dark_dropout(strength_albedo: np.ndarray, cfg: FieldLidarConfig, rng: np.random.Generator) -> np.ndarray:
    """Mask of returns that survive: below `dark_albedo` (albedo x cos incidence) the survival
    probability falls linearly to zero."""
    keep_p = np.clip(strength_albedo / max(cfg.dark_albedo, 1e-9), 0.0, 1.0)
    return rng.random(strength_albedo.shape) < keep_p


@dataclass(frozen=True)
class Puddles:
    centres: np.ndarray  # (P, 2) m, map frame
    radii: np.ndarray  # (P,) m

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """(N,) bool for (N, 2) points."""
        inside = np.zeros(len(xy), bool)
        for c, r in zip(self.centres, self.radii, strict=True):
            inside |= np.sum((xy - c) ** 2, axis=1) < r * r
        return inside


def scatter_puddles(centre: tuple[float, float], half_size_m: float, cfg: FieldLidarConfig,
                    rng: np.random.Generator) -> Puddles:
    n = rng.poisson(cfg.wet_patches_per_100m2 * (2 * half_size_m) ** 2 / 100.0)
    xy = np.asarray(centre, float) + rng.uniform(-half_size_m, half_size_m, (n, 2))
    return Puddles(xy, rng.uniform(*cfg.wet_patch_radius_m, n))


@dataclass(frozen=True)
class MovingBox:
    """A box (vehicle or person) that goes back and forth along a straight line at constant
    speed: centre(t) = start + direction * s(t), s a triangle wave over [0, length]."""

    start_xy: np.ndarray  # (2,) m
    direction: np.ndarray  # (2,) unit
    length_m: float
    speed_mps: float
    phase_s: float
    size: tuple[float, float, float]  # m, along, across, height
    albedo: float

    def centre_xy(self, times: np.ndarray) -> np.ndarray:
        period = 2 * self.length_m / self.speed_mps
        tt = np.mod(np.asarray(times, float) + self.phase_s, period)
        s = self.speed_mps * np.where(tt < period / 2, tt, period - tt)
        return self.start_xy + s[:, None] * self.direction


MOVING_SHAPES = {"vehicle": ((4.5, 1.9, 1.6), 0.45), "person": ((0.4, 0.6, 1.8), 0.3)}  # m; NIR albedo


def place_moving_box(kind: str, robot_xy: np.ndarray, robot_t: np.ndarray, centre: tuple[float, float],
                     speed_mps: float, clearance_m: float, robot_half_length_m: float,
                     rng: np.random.Generator) -> MovingBox:
    """A crossing line through the middle of the driven area with a random direction; the phase
    is redrawn until the object keeps `clearance_m` (plus both half-lengths) from the machine."""
    size, albedo = MOVING_SHAPES[kind]
    reach = float(np.max(np.linalg.norm(robot_xy - np.asarray(centre), axis=1))) + 10.0
    keep = clearance_m + robot_half_length_m + size[0] / 2
    box = None
    for _ in range(200):
        heading = rng.uniform(0.0, np.pi)
        d = np.array([math.cos(heading), math.sin(heading)])
        box = MovingBox(np.asarray(centre, float) - reach * d, d, 2 * reach, speed_mps,
                        rng.uniform(0.0, 4 * reach / speed_mps), size, albedo)
        if np.min(np.linalg.norm(box.centre_xy(robot_t) - robot_xy, axis=1)) >= keep:
            return box
    assert box is not None
    return box
