"""Exit 1 when a metric gate fails: `slam` and `report` judge what they wrote (README, exit codes)."""

from __future__ import annotations

from mrnc_eval.errors import GateFailed
from mrnc_eval.evaluation.config import GatesConfig
from mrnc_eval.results import RunResult


def raise_on_failed_gates(results: list[RunResult], gates: GatesConfig) -> None:
    """GateFailed naming each failed gate with its worst value and limit; nothing when all pass."""
    from mrnc_eval.reports.gates import evaluate_gates

    failed = [g for g in evaluate_gates(results, gates) if g.status == "fail"]
    if failed:
        raise GateFailed("gates failed: " + "; ".join(f"{g.label} {g.value} (limit {g.limit})" for g in failed))
