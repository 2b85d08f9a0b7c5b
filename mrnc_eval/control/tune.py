"""Equal-effort tuning (issue 25 item 6): every law's free parameters searched with the same
optimiser, cost and budget on the nominal plant, so no law is compared at hand-tuned gains against
another at printed ones.

Optimiser: the law's configured gains first, then budget - 1 points of a scrambled Halton sequence
(seeded) over the box below, in log space where a bound spans decades; the best point is kept. Cost
(one for all laws): IAE of both sides (m, full rate, up to a stop) + stop_penalty per side that
stopped + violation_penalty per side that left the funnel (|e| >= o(t)) while running.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import qmc

from mrnc_eval.control.closed_loop import ST_FUNNEL, ST_IAE, run_closed_loop
from mrnc_eval.control.config import ControlConfig, RobotGeometry
from mrnc_eval.control.scenario import Scenario

# law -> (config section, parameter, low, high, log-spaced)
SPACE: dict[str, list[tuple[str, str, float, float, bool]]] = {
    "raid": [("raid", "feedback_scale_rpm", 0.3, 300.0, True), ("raid", "beta", 0.1, 50.0, True)],
    "pid": [("pid", "kp", 500.0, 20000.0, True), ("pid", "ki", 100.0, 50000.0, True)],
    "apc": [("apc", "rho", 0.05, 1.0, True), ("apc", "lam", 0.1, 10.0, True)],
    "foptc": [("foptc", "k0", 0.5, 10.0, True), ("foptc", "ki", 0.1, 20.0, True)],
}


@dataclass(frozen=True, kw_only=True)
class TuneResult:
    law: str
    params: dict[str, float]  # "section.name" -> value found
    start_params: dict[str, float]  # the configured (paper / default) values
    cost: float
    start_cost: float
    evaluations: int


def with_params(cfg: ControlConfig, params: dict[str, float]) -> ControlConfig:
    """cfg with "section.name" parameters replaced."""
    for key, value in params.items():
        section, name = key.split(".")
        cfg = replace(cfg, **{section: replace(getattr(cfg, section), **{name: float(value)})})
    return cfg


def run_cost(tr_stats: np.ndarray, stopped_sides: int, *, stop_penalty: float, violation_penalty: float) -> float:
    """The tuning cost of one run from its full-rate counters (2, N_STATS) and stopped sides."""
    violated = int(np.count_nonzero(tr_stats[:, ST_FUNNEL] > 0))
    return float(tr_stats[:, ST_IAE].sum() + stop_penalty * stopped_sides + violation_penalty * violated)


def tune_law(law: str, scenario: Scenario, cfg: ControlConfig, robot: RobotGeometry, *, budget: int, seed: int,
             duration_s: float, noise_seed: int, stop_penalty: float = 5.0, violation_penalty: float = 1.0,
             progress: Callable[[str, int], None] | None = None) -> TuneResult:
    """Search the law's box with `budget` closed-loop runs of `duration_s` s (noise seed `noise_seed`)."""
    space = SPACE[law]
    start = {f"{s}.{n}": float(getattr(getattr(cfg, s), n)) for s, n, *_ in space}

    def cost(params: dict[str, float]) -> float:
        c = with_params(cfg, params)
        tr = run_closed_loop(scenario, c, robot, law, duration_s=duration_s, seed=noise_seed, record_every=50)
        assert tr.full_rate_stats is not None
        return run_cost(tr.full_rate_stats, len({e["side"] for e in tr.events}), stop_penalty=stop_penalty,
                        violation_penalty=violation_penalty)

    best_p, best_c = start, cost(start)
    start_c = best_c
    if budget > 1:
        pts = qmc.Halton(d=len(space), scramble=True, seed=seed).random(budget - 1)
        for k, u in enumerate(pts):
            params = {}
            for (s, n, lo, hi, log), x in zip(space, u, strict=True):
                params[f"{s}.{n}"] = float(np.exp(np.log(lo) + x * (np.log(hi) - np.log(lo))) if log
                                           else lo + x * (hi - lo))
            c = cost(params)
            if progress is not None:
                progress(law, k + 2)
            if c < best_c:
                best_p, best_c = params, c
    return TuneResult(law=law, params=best_p, start_params=start, cost=best_c, start_cost=start_c,
                      evaluations=max(budget, 1))
