"""Evaluation defaults and the pass/fail gates used by reports and the nightly job."""

from __future__ import annotations

from dataclasses import dataclass

from mrnc_eval.params import param


@dataclass(frozen=True)
class EvaluationConfig:
    """Trajectory evaluation defaults: association tolerances, time offset, when a run counts as failed."""

    max_diff_s: float = param(0.01, "association: maximum stamp difference", "s", ge=0.0)
    gt_max_diff_s: float = param(
        0.01, "slam and export: maximum stamp difference when pairing the estimate with the ground truth "
        "(as `mrnc-eval ape`'s --max-diff default, so a result's APE is the one the verb gives on its files)",
        "s", ge=0.0)
    gnss_max_diff_s: float = param(
        0.1, "slam: maximum stamp difference when pairing the antenna track with GNSS fixes (half the period of a "
        "5 Hz receiver)", "s", ge=0.0)
    offset_s: float = param(0.0, "association: added to the estimate's clock", "s", ge=-86_400.0, le=86_400.0)
    failed_min_span_fraction: float = param(
        0.8, "tables: a method whose matched span is shorter than this fraction of the reference is 'Failed'",
        ge=0.0, le=1.0)
    failed_min_matches: int = param(10, "tables: fewer matched poses than this is 'Failed'", ge=1)


@dataclass(frozen=True)
class GatesConfig:
    """Pass/fail limits of reports and the nightly job."""

    ape_rmse_max_m: float = param(0.10, "SLAM gate: APE translation RMSE after SE(3) alignment", "m", ge=0.0)
    funnel_violations_max: int = param(0, "control gate: samples with |e| >= o(t), per side", ge=0)
    saturation_ratio_max: float = param(0.2, "control gate: fraction of samples at the RPM limit", ge=0.0, le=1.0)
    safety_stops_max: int = param(0, "control gate: safety-stop events", ge=0)
