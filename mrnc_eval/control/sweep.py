"""Robustness sweep: plants drawn from the ranges in control.sweep, applied to the control config
and the scenario. Pure: the draws are a function of (ranges, n, seed); every controller is run on
the same draws by the caller (commands/control_sweep.py)."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np

from mrnc_eval.control.config import ControlConfig, DriveConfig, PlantConfig, SweepConfig
from mrnc_eval.control.jit_cache import FloatArray
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


def slip_demands(v_ref: list[FloatArray], slip: list[FloatArray]) -> list[tuple[float, float]]:
    """(slip ratio, highest side reference m/s while on it) of a nominal run, sides pooled; slip 0 =
    the highest reference anywhere. What a drawn plant must deliver where it slips most."""
    refs, slips = np.concatenate(v_ref), np.concatenate(slip)
    out = [(0.0, float(np.max(np.abs(refs))))]
    for ratio in np.unique(slips[slips > 0]):
        out.append((float(ratio), float(np.max(np.abs(refs[slips == ratio])))))
    return out


def authority_margin(draw: PlantDraw, demands: list[tuple[float, float]], cfg: ControlConfig) -> float:
    """Worst speed margin (m/s) of the drawn drive at the clamp: min over the nominal run's demands of
    K (1 - s') (U_top - dz) - v_ref, with s' the draw's scaled slip (capped at 0.95) and U_top = u_max
    (clamp on the total command) or f(v_ref) + u_max (clamp on the feedback). Static map of the drive
    (v = K (1 - s) deadband(U))."""
    gain = (1.0 + draw.gain_mismatch) / cfg.model.feedforward_rpm_per_mps
    worst = float("inf")
    for ratio, v in demands:
        top = cfg.actuator.u_max_rpm
        if cfg.actuator.saturation_applies_to == "feedback":
            top += cfg.model.feedforward_rpm_per_mps * v
        s_draw = min(ratio * draw.slip_scale, 0.95)
        worst = min(worst, gain * (1.0 - s_draw) * max(top - draw.dead_band_rpm, 0.0) - v)
    return worst


def feasible(draw: PlantDraw, demands: list[tuple[float, float]], cfg: ControlConfig) -> bool:
    """A plant on which some controller can hold |e| < o_b everywhere: the clamp and the slip leave a
    reachable speed within the funnel floor o_b of every demand."""
    return margin_is_feasible(authority_margin(draw, demands, cfg), cfg)


def margin_is_feasible(margin_mps: float, cfg: ControlConfig) -> bool:
    """The feasibility rule on an authority margin already computed (m/s)."""
    return margin_mps > -cfg.funnel.o_b_mps


def wilson_interval(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval (95 % by default) of a fraction k/n; (nan, nan) for n = 0."""
    if n == 0:
        return float("nan"), float("nan")
    p = k / n
    den = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * float(np.sqrt(p * (1 - p) / n + z * z / (4 * n * n))) / den
    return max(0.0, centre - half), min(1.0, centre + half)


def mismatch_bins(cfg: SweepConfig, n_bins: int = 6) -> list[tuple[float, float]]:
    """Equal-width gain-mismatch bins over the configured range, for violation rate against mismatch."""
    edges = np.linspace(cfg.gain_mismatch[0], cfg.gain_mismatch[1], n_bins + 1)
    return [(float(a), float(b)) for a, b in itertools.pairwise(edges)]
