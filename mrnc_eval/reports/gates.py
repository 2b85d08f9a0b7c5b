"""The metric gates (pass/fail cards) of results: what `slam` and `report` exit 1 on, what reports
show and JUnit lists. Apart from reports/render.py (which re-exports them) so that judging a run's
gates does not import the report stack (markupsafe, jinja2's helpers)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

from mrnc_eval.evaluation.config import GatesConfig
from mrnc_eval.reports.tables import is_number
from mrnc_eval.results import RunResult
from mrnc_eval.schema import slam as S
from mrnc_eval.text import printable

DEPLOYED = ("raid", "recorded")  # control gates judge the deployed controller (RAID in simulation, the log in replay)


@dataclass(frozen=True)
class Gate:
    """One pass/fail gate of a report."""

    label: str
    value: str
    limit: str
    status: Literal["pass", "fail", "na"]


def evaluate_gates(results: list[RunResult], gates: GatesConfig) -> list[Gate]:
    """Pass/fail cards: APE RMSE, funnel violations, saturation, safety stops (worst value). A gate
    whose metric is present but not a finite number (text, null from a NaN, inf) fails, naming the
    value: it is never skipped ("n/a" only when no result has the metric at all)."""
    def values(kind: str, name: str, method: str | None = None) -> list[Any]:
        return [m.value for r in results if r.kind == kind and (method is None or r.extra.get(S.METHOD) == method)
                for m in r.metrics
                if m.name == name and (kind != "control" or m.group.split("/")[1:2] in [[d] for d in DEPLOYED])]

    def card(label: str, vals: list[Any], limit: float, fmt: str, unit: str = "") -> Gate:
        if not vals:
            return Gate(label, "n/a", f"{limit:g}{unit}", "na")
        bad = [v for v in vals if not is_number(v)]
        if bad:
            return Gate(label, f"not a finite number: {printable(repr(bad[0]))[:40]}", f"{limit:g}{unit}", "fail")
        worst = max(vals)
        return Gate(label, fmt.format(worst) + unit, f"{limit:g}{unit}", "pass" if worst <= limit else "fail")

    def ape_cards() -> list[Gate]:  # one per SLAM method, named when the result says which
        methods = list(dict.fromkeys(str(r.extra[S.METHOD]) for r in results if r.kind == "slam"
                                     and r.extra.get(S.METHOD)))
        if len(methods) == 0:
            return [card("APE RMSE", values("slam", "ape_rmse_m"), gates.ape_rmse_max_m, "{:.3f}", " m")]
        return [card(f"APE RMSE ({method})", values("slam", "ape_rmse_m", method), gates.ape_rmse_max_m, "{:.3f}",
                     " m") for method in methods]

    return [*ape_cards(),
            card("Funnel violations", values("control", "funnel_violations"), gates.funnel_violations_max, "{:.0f}"),
            card("Saturation ratio", values("control", "saturation_ratio"), gates.saturation_ratio_max, "{:.3f}"),
            card("Safety stops", values("control", "safety_stops"), gates.safety_stops_max, "{:.0f}")]
