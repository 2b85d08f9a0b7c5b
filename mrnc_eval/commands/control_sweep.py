"""`mrnc-eval control --mode sweep`: every controller on the same N drawn plants (control.sweep),
in parallel worker processes, summarised per controller (fractions of runs with a funnel violation,
a safety stop, saturation above the limit; median and p95 of steady-state error, IAE, cross-track
RMS) and as violation rate against gain mismatch."""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from mrnc_eval.config import Config, config_hash, dump_config
from mrnc_eval.control.closed_loop import SIDES, ST_FUNNEL, ST_IAE, ST_RESTARTS, ST_SATURATED, run_closed_loop
from mrnc_eval.control.config import shaping_text
from mrnc_eval.control.controllers import LABELS, STOP_CAUSES
from mrnc_eval.control.scenario import paper_circle_scenario
from mrnc_eval.control.sweep import (
    PlantDraw,
    authority_margin,
    draw_plants,
    margin_is_feasible,
    mismatch_bins,
    plant_for,
    scenario_for,
    slip_demands,
    wilson_interval,
)
from mrnc_eval.errors import UsageError
from mrnc_eval.evaluation.control_metrics import cross_track, paper_metrics
from mrnc_eval.results import RunResult, write_result
from mrnc_eval.schema import control as K
from mrnc_eval.tables import Table


@dataclass(frozen=True, kw_only=True)
class SweepRun:
    """One controller on one drawn plant (worst side where a metric is per side)."""

    draw: int
    controller: str
    gain_mismatch: float
    funnel_violation: bool  # any control period with |e| >= o(t), either side
    safety_stop: bool
    saturation_fraction: float  # of control periods at the limit, worst side
    steady_state_error_mps: float  # paper reading: mean |r - v| over steady cruise, worst side
    iae_m: float  # full rate, worst side
    cross_track_rms_m: float
    completed: bool
    feasible: bool = True  # control.sweep.feasible: the clamp and the slip leave |e| < o_b reachable
    authority_margin_mps: float = float("nan")
    stop_cause: str = ""  # first safety stop: barrier, barrier_at_clamp, non_finite ("" = none)
    stop_side: str = ""
    stop_time_s: float = float("nan")
    stop_e_over_o: float = float("nan")
    restarts: int = 0  # step restarts of the per-step clocks, most on one side


def nominal_demands(cfg: Config) -> list[tuple[float, float]]:
    """Slip demands of the paper circle driven by the feed-forward alone on the nominal plant."""
    c = cfg.control
    tr = run_closed_loop(paper_circle_scenario(c), c, cfg.robot, "ff", duration_s=c.sweep.duration_s,
                         record_every=c.sweep.record_every)
    return slip_demands([tr.v_ref_left, tr.v_ref_right], [tr.slip_left, tr.slip_right])


def run_one(draw: PlantDraw, controller: str, cfg: Config, seed: int,
            demands: list[tuple[float, float]] | None = None) -> SweepRun:
    """Simulate the paper circle with `controller` on the drawn plant and summarise it."""
    c = cfg.control
    s = c.sweep
    scenario = scenario_for(draw, paper_circle_scenario(c))
    cfg_run = replace(c, plant=plant_for(draw, c))
    tr = run_closed_loop(scenario, cfg_run, cfg.robot, controller, duration_s=s.duration_s, seed=seed,
                         record_every=s.record_every)
    stats = tr.full_rate_stats if tr.full_rate_stats is not None else np.zeros((2, 4))
    n_periods = max(1, int(round(tr.t[-1] * c.rate_hz)) + 1)
    stop_at = {e["side"]: e["t_s"] for e in tr.events}
    sse = []
    for side in SIDES:  # up to a safety stop: a stopped side's dead error is not tracking
        keep = tr.t <= stop_at.get(side, np.inf)
        st = tr.side(side)
        sse.append(paper_metrics(tr.t[keep], st.v_ref[keep], st.v_wheel[keep], c.paper_metrics)
                   ["paper_steady_state_error_mps"] if keep.sum() > 2 else float("nan"))
    cte, _ = cross_track(tr.x, tr.y, scenario.waypoints_xy)
    first = min(tr.events, key=lambda e: e["t_s"]) if tr.events else None
    demands = demands if demands is not None else nominal_demands(cfg)
    margin = authority_margin(draw, demands, c)
    return SweepRun(draw=draw.index, controller=controller, gain_mismatch=draw.gain_mismatch,
                    funnel_violation=bool(stats[:, ST_FUNNEL].max() > 0), safety_stop=bool(tr.events),
                    saturation_fraction=float(stats[:, ST_SATURATED].max() / n_periods),
                    steady_state_error_mps=float(np.nanmax(sse)) if not np.all(np.isnan(sse)) else float("nan"),
                    iae_m=float(stats[:, ST_IAE].max()), cross_track_rms_m=float(np.sqrt(np.mean(cte ** 2))),
                    completed=tr.completed, feasible=margin_is_feasible(margin, c),
                    authority_margin_mps=margin,
                    stop_cause=first["cause"] if first else "", stop_side=first["side"] if first else "",
                    stop_time_s=float(first["t_s"]) if first else float("nan"),
                    stop_e_over_o=float(first["e_over_o"]) if first else float("nan"),
                    restarts=int(stats[:, ST_RESTARTS].max()))


def run_chunk(draws: list[PlantDraw], controllers: tuple[str, ...], cfg: Config, seed: int,
              demands: list[tuple[float, float]]) -> list[SweepRun]:
    """A worker's share: every controller on each of `draws` (noise seed: seed + draw index)."""
    return [run_one(d, n, cfg, seed + d.index, demands) for d in draws for n in controllers]


def run_sweep(cfg: Config, controllers: tuple[str, ...], runs: int, seed: int,
              workers: int | None = None) -> list[SweepRun]:
    """All (draw, controller) pairs, in `workers` spawned processes (default: control.sweep.workers,
    0 = all cores; 1 = in this process). Results are ordered by draw, then controller."""
    draws = draw_plants(cfg.control.sweep, runs, seed)
    workers = workers if workers is not None else (cfg.control.sweep.workers or os.cpu_count() or 1)
    demands = nominal_demands(cfg)
    if workers <= 1 or runs <= 1:
        return run_chunk(draws, controllers, cfg, seed, demands)
    chunks = [draws[k::workers * 4] for k in range(min(runs, workers * 4))]  # small tasks balance the load
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
        parts = list(pool.map(run_chunk, chunks, [controllers] * len(chunks), [cfg] * len(chunks),
                              [seed] * len(chunks), [demands] * len(chunks)))
    order = {n: k for k, n in enumerate(controllers)}
    return sorted((r for part in parts for r in part), key=lambda r: (r.draw, order[r.controller]))


def _by_controller(runs: list[SweepRun], controllers: tuple[str, ...]) -> Iterator[tuple[str, list[SweepRun]]]:
    for n in controllers:
        yield n, [r for r in runs if r.controller == n]


def _stat(values: list[float], q: float) -> float:
    arr = np.asarray(values, dtype=float)
    arr = arr[np.isfinite(arr)]
    return float(np.percentile(arr, q)) if arr.size else float("nan")


def summarise(runs: list[SweepRun], controllers: tuple[str, ...], cfg: Config) -> dict[str, dict[str, Any]]:
    """Per controller: run counts and fractions, median / p95 of the per-run metrics, and the
    funnel-violation rate per gain-mismatch bin."""
    limit = cfg.control.sweep.saturation_limit
    bins = mismatch_bins(cfg.control.sweep)
    out: dict[str, dict[str, Any]] = {}
    for name, rs in _by_controller(runs, controllers):
        n = len(rs)
        per_bin = []
        for lo, hi in bins:
            inside = [r for r in rs if lo <= r.gain_mismatch < hi or (hi == bins[-1][1] and r.gain_mismatch == hi)]
            per_bin.append({"gain_mismatch_lo": lo, "gain_mismatch_hi": hi, "runs": len(inside),
                            "funnel_violation_rate": (sum(r.funnel_violation for r in inside) / len(inside)
                                                      if inside else float("nan"))})
        out[name] = {
            "label": LABELS.get(name, name), "runs": n,
            "runs_with_funnel_violation": sum(r.funnel_violation for r in rs),
            "runs_with_safety_stop": sum(r.safety_stop for r in rs),
            "runs_with_saturation": sum(r.saturation_fraction > limit for r in rs),
            "runs_completed": sum(r.completed for r in rs),
            "funnel_violation_fraction": sum(r.funnel_violation for r in rs) / n if n else float("nan"),
            "safety_stop_fraction": sum(r.safety_stop for r in rs) / n if n else float("nan"),
            "saturation_fraction": sum(r.saturation_fraction > limit for r in rs) / n if n else float("nan"),
            **{f"{key}_{q_name}": _stat([getattr(r, key) for r in rs], q)
               for key in ("steady_state_error_mps", "iae_m", "cross_track_rms_m")
               for q_name, q in (("median", 50.0), ("p95", 95.0))},
            "violation_rate_by_gain_mismatch": per_bin,
            **_by_feasibility(rs),
            "stop_causes": {cause: sum(r.stop_cause == cause for r in rs) for cause in STOP_CAUSES.values()},
            "time_to_stop_s_median": _stat([r.stop_time_s for r in rs], 50.0),
            "funnel_violation_fraction_ci95": list(wilson_interval(sum(r.funnel_violation for r in rs), n)),
            "safety_stop_fraction_ci95": list(wilson_interval(sum(r.safety_stop for r in rs), n)),
        }
    return out


def _by_feasibility(rs: list[SweepRun]) -> dict[str, Any]:
    """Run counts, violation and stop fractions with Wilson 95 % intervals, for feasible and
    infeasible plants apart (a plant the clamp and the slip make infeasible says nothing about a law)."""
    out: dict[str, Any] = {}
    for group, keep in (("feasible", True), ("infeasible", False)):
        g = [r for r in rs if r.feasible == keep]
        out[f"{group}_runs"] = len(g)
        for what, flag in (("funnel_violation", "funnel_violation"), ("safety_stop", "safety_stop")):
            k = sum(getattr(r, flag) for r in g)
            out[f"{group}_{what}_fraction"] = k / len(g) if g else float("nan")
            out[f"{group}_{what}_fraction_ci95"] = list(wilson_interval(k, len(g)))
    return out


SWEEP_ROWS = [("Runs with a funnel violation (fraction)", "funnel_violation_fraction"),
              ("Runs with a safety stop (fraction)", "safety_stop_fraction"),
              ("Feasible plants (runs)", "feasible_runs"),
              ("  violation fraction [95 % CI]", "feasible_funnel_violation_fraction"),
              ("  stop fraction [95 % CI]", "feasible_safety_stop_fraction"),
              ("Infeasible plants (runs)", "infeasible_runs"),
              ("  violation fraction [95 % CI]", "infeasible_funnel_violation_fraction"),
              ("  stop fraction [95 % CI]", "infeasible_safety_stop_fraction"),
              ("Time to stop, median (s)", "time_to_stop_s_median"),
              ("Runs saturated > {limit:g} % of the time (fraction)", "saturation_fraction"),
              ("Steady-state error, median (m/s)", "steady_state_error_mps_median"),
              ("Steady-state error, p95 (m/s)", "steady_state_error_mps_p95"),
              ("IAE, median (m)", "iae_m_median"), ("IAE, p95 (m)", "iae_m_p95"),
              ("Cross-track RMS, median (m)", "cross_track_rms_m_median"),
              ("Cross-track RMS, p95 (m)", "cross_track_rms_m_p95")]


def _with_ci(smry: dict[str, Any], key: str) -> Any:
    """A fraction with its Wilson 95 % interval as text, where the summary has one."""
    ci = smry.get(f"{key}_ci95")
    v = smry[key]
    if ci is None or not isinstance(v, float) or np.isnan(v):
        return v
    return f"{v:.3f} [{ci[0]:.3f}, {ci[1]:.3f}]"


def sweep_table(summary: dict[str, dict[str, Any]], cfg: Config, runs: int, seed: int) -> Table:
    s = cfg.control.sweep
    names = list(summary)
    cells = [[_with_ci(summary[n], key) for n in names] for _label, key in SWEEP_ROWS]
    notes = [
        f"{runs} plants drawn uniformly (seed {seed}): gain mismatch {s.gain_mismatch[0]:+.0%} .. "
        f"{s.gain_mismatch[1]:+.0%} of the controllers' 1/{cfg.control.model.feedforward_rpm_per_mps:g} (m/s)/RPM, "
        f"dead band {s.dead_band_rpm[0]:g}-{s.dead_band_rpm[1]:g} RPM, delay {1000 * s.delay_s[0]:g}-"
        f"{1000 * s.delay_s[1]:g} ms, time constant {s.tau_s[0]:g}-{s.tau_s[1]:g} s, slip ratios of the paper "
        f"circle's patches x {s.slip_scale[0]:g}-{s.slip_scale[1]:g}; every controller on the same draws, "
        f"{s.duration_s:g} s at {cfg.control.rate_hz:g} Hz.",
        f"Funnel violation: any control period with |e| >= o(t) on either side. Saturated: |U| within "
        f"{cfg.control.metrics.saturation_tolerance_rpm:g} RPM of {cfg.control.actuator.u_max_rpm:g} RPM for more than "
        f"{100 * s.saturation_limit:g} % of the periods on a side. Steady-state error: the paper reading (mean |r - v| "
        f"over steady cruise), worst side. IAE: full rate, worst side.",
        f"Feasible plant: for every slip patch (and off them) K (1 - s) (U_top - dz) > v_ref - o_b, with v_ref the "
        f"highest side reference on that patch in a nominal feed-forward run and U_top the clamp "
        f"({cfg.control.actuator.saturation_applies_to} command): the drive can stay within the funnel floor o_b = "
        f"{cfg.control.funnel.o_b_mps:g} m/s. Fractions with Wilson 95 % intervals.",
        f"Safety stop on funnel exit for: {cfg.control.supervisor.stop_rule} (control.supervisor.stop_rule); counts, "
        "IAE and steady-state error run up to a side's stop; stop causes: barrier, barrier_at_clamp (previous command "
        "at the clamp), non_finite. "
        f"{shaping_text(cfg.control).capitalize()}; RAID output unit "
        f"{cfg.control.raid.output_unit} x {cfg.control.raid.feedback_scale_rpm:g}.",
        "APC and FOPTC are stand-ins; FF only is the negative control (no feedback).",
    ]
    return Table(title="Robustness sweep: fraction of runs and distributions per controller",
                 row_labels=[r[0].format(limit=100 * s.saturation_limit) for r in SWEEP_ROWS],
                 column_labels=[LABELS.get(n, n) for n in names],
                 cells=cells, best="min", precision=3, notes=notes)


def runs_as_rows(runs: list[SweepRun]) -> list[dict[str, Any]]:
    return [asdict(r) for r in runs]


MAX_SWEEP_RUNS = 100_000  # as control.sweep.runs declares


def run_sweep_result(cfg: Config, names: tuple[str, ...], out_dir: Path, *, runs: int | None,
                     seed: int | None) -> RunResult:
    """The robustness sweep as a result: summary table, per-run rows and violation rate by gain mismatch."""
    n = cfg.control.sweep.runs if runs is None else runs
    s = cfg.control.sweep.seed if seed is None else seed
    if not 1 <= n <= MAX_SWEEP_RUNS:  # name where the number came from: the flag or the configuration
        where = "--runs" if runs is not None else "control.sweep.runs (configuration)"
        raise UsageError(f"{where} {n}: must be 1 .. {MAX_SWEEP_RUNS}")
    rows = run_sweep(cfg, names, n, s)
    summary = summarise(rows, names, cfg)
    table = sweep_table(summary, cfg, n, s)
    result = RunResult(kind="control", log_path="paper-scenario (sweep)", log_id="paper-circle",
                       config_hash=config_hash(cfg), tables=[table])
    first = next(iter(summary.values()))
    bins = first["violation_rate_by_gain_mismatch"]
    assert isinstance(bins, list)
    result.series[K.SWEEP_GAIN_MISMATCH_MID] = np.array([0.5 * (b["gain_mismatch_lo"] + b["gain_mismatch_hi"])
                                                         for b in bins])
    for name, smry in summary.items():
        per_bin = smry["violation_rate_by_gain_mismatch"]
        assert isinstance(per_bin, list)
        result.series[K.sweep_violation_rate(name)] = np.array([b["funnel_violation_rate"] for b in per_bin])
    result.extra = {K.MODE: "sweep", K.CONTROLLERS: list(names), K.LABELS: {n_: LABELS.get(n_, n_) for n_ in names},
                    K.RUNS: n, "seed": s, "sweep": summary, "sweep_runs": runs_as_rows(rows),
                    "supervisor": cfg.control.supervisor.stop_rule, "shaping": shaping_text(cfg.control),
                    K.DEFINITIONS: table.notes}
    write_result(result, out_dir, dump_config(cfg))
    return result

