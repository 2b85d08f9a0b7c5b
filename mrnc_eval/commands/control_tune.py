"""`mrnc-eval control --mode tune`: every law tuned with the same optimiser, cost and budget on the
nominal plant (control/tune.py), then Table II's paper criteria at the configured ("paper") gains and
at the tuned ones, reported on a different noise seed than the tuning runs."""

from __future__ import annotations

from pathlib import Path

from mrnc_eval.config import Config, config_hash, dump_config
from mrnc_eval.control.closed_loop import run_closed_loop
from mrnc_eval.control.controllers import LABELS
from mrnc_eval.control.scenario import paper_circle_scenario
from mrnc_eval.control.tune import SPACE, TuneResult, tune_law, with_params
from mrnc_eval.evaluation.control_run import evaluate_trace
from mrnc_eval.reports.control_tables import tune_table
from mrnc_eval.results import RunResult, write_result


def run_tune(cfg: Config, names: tuple[str, ...], out_dir: Path) -> RunResult:
    c, t = cfg.control, cfg.control.tune
    scenario = paper_circle_scenario(c)
    laws = [n for n in names if n in SPACE]
    found: dict[str, TuneResult] = {}
    metrics: dict[str, dict[str, dict[str, dict[str, float]]]] = {}
    for law in laws:
        found[law] = tune_law(law, scenario, c, cfg.robot, budget=t.budget, seed=t.seed, duration_s=t.duration_s,
                              noise_seed=c.seed + t.noise_seed_offset, stop_penalty=t.stop_penalty_m,
                              violation_penalty=t.violation_penalty_m)
        metrics[law] = {}
        for column, params in (("paper", found[law].start_params), ("tuned", found[law].params)):
            run_cfg = with_params(c, params)
            metrics[law][column] = evaluate_trace(run_closed_loop(scenario, run_cfg, cfg.robot, law), run_cfg)
    result = RunResult(kind="control", log_path="paper-scenario (tune)", log_id="paper-circle",
                       config_hash=config_hash(cfg), tables=[tune_table(metrics, found, cfg)])
    result.extra = {"mode": "tune", "controllers": laws, "labels": {n: LABELS.get(n, n) for n in laws},
                    "optimiser": f"configured gains + {t.budget - 1} scrambled Halton points (seed {t.seed}) in the "
                                 "law's box, log-spaced",
                    "cost": f"IAE both sides (m) + {t.stop_penalty_m:g} m per stopped side + "
                            f"{t.violation_penalty_m:g} m per side leaving the funnel",
                    "budget": t.budget, "tuning_noise_seed": c.seed + t.noise_seed_offset, "report_noise_seed": c.seed,
                    "tuned": {law: {"params": r.params, "start_params": r.start_params, "cost": r.cost,
                                    "start_cost": r.start_cost, "evaluations": r.evaluations,
                                    "box": {f"{s}.{n}": [lo, hi] for s, n, lo, hi, _ in SPACE[law]}}
                              for law, r in found.items()},
                    "definitions": result_notes(cfg)}
    write_result(result, out_dir, dump_config(cfg))
    return result


def result_notes(cfg: Config) -> list[str]:
    t = cfg.control.tune
    return [f"Same optimiser, cost and budget ({t.budget} closed-loop runs of {t.duration_s:g} s) for every law on "
            "the nominal plant; feed-forward only has nothing to tune."]
