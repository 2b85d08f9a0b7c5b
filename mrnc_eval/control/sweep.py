"""Robustness sweep: plants drawn from the ranges in control.sweep, applied to the control config
and the scenario. Pure: the draws are a function of (ranges, n, seed); every controller is run on
the same draws by the caller (commands/control_sweep.py)."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np

from mrnc_eval.control.config import ControlConfig, DriveConfig, PlantConfig, SweepConfig
from mrnc_eval.control.plant import SlipPatch
from mrnc_eval.control.scenario import Scenario


@dataclass(frozen=True)
class PlantDraw:
    """One drawn plant (both sides alike). gain_mismatch m: K = (1 + m) / feed-forward gain."""

    index: int
    gain_mismatch: float
    dead_band_rpm: float
    delay_s: float
    tau_s: float
    slip_scale: float


def draw_plants(cfg: SweepConfig, n: int, seed: int) -> list[PlantDraw]:
    """n plants, each parameter uniform in its configured range (independent draws). Drawn plant by
    plant, so the first m of n draws are the m draws of a smaller sweep with the same seed."""
    rng = np.random.default_rng(seed)
    ranges = (cfg.gain_mismatch, cfg.dead_band_rpm, cfg.delay_s, cfg.tau_s, cfg.slip_scale)
    return [PlantDraw(k, *(float(rng.uniform(lo, hi)) for lo, hi in ranges)) for k in range(n)]


def plant_for(draw: PlantDraw, cfg: ControlConfig) -> PlantConfig:
    """The control config's plant with the drawn drive on both sides."""
    drive = DriveConfig(gain_mps_per_rpm=(1.0 + draw.gain_mismatch) / cfg.model.feedforward_rpm_per_mps,
                        tau_s=draw.tau_s, delay_s=draw.delay_s, dead_band_rpm=draw.dead_band_rpm)
    return replace(cfg.plant, left=drive, right=drive)


def scenario_for(draw: PlantDraw, scenario: Scenario) -> Scenario:
    """The scenario with every slip ratio scaled by the draw's severity (capped below 1)."""
    patches = tuple(SlipPatch(p.x, p.y, p.radius_m, min(p.slip * draw.slip_scale, 0.95))
                    for p in scenario.slip_patches)
    return replace(scenario, slip_patches=patches)


def mismatch_bins(cfg: SweepConfig, n_bins: int = 6) -> list[tuple[float, float]]:
    """Equal-width gain-mismatch bins over the configured range, for violation rate against mismatch."""
    edges = np.linspace(cfg.gain_mismatch[0], cfg.gain_mismatch[1], n_bins + 1)
    return [(float(a), float(b)) for a, b in itertools.pairwise(edges)]
