"""Two runs side by side: the same metrics with their difference, and the configuration keys
that differ. Builds `Table`s (rendered by reports.tables as Markdown or HTML, or by the CLI for
the terminal); knows nothing about where the numbers came from (result directories or the
nightly history)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from mrnc_eval.tables import Cell, Table


@dataclass(frozen=True)
class RunMetrics:
    """One side of a comparison. `metrics`: key ("slam/ape/ape_rmse_m") -> (value, unit);
    `config`: the effective configuration as dotted keys (None when unknown)."""

    label: str
    metrics: Mapping[str, tuple[float | None, str]]
    config: Mapping[str, Any] | None = None
    lower_is_better: Mapping[str, bool | None] = field(default_factory=dict)  # None or absent: unknown
    logs: frozenset[str] = frozenset()  # the log path(s) the metrics come from
    kinds: frozenset[str] = frozenset()  # slam, control, info


def flatten(tree: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """{"a": {"b": 1}} -> {"a.b": 1}."""
    out: dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(flatten(value, name + "."))
        else:
            out[name] = value
    return out


def _number(v: float | None) -> bool:
    """A number, infinities included (a diverged run's inf is a value), NaN not."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and not math.isnan(v)


def _change(key: str, a: float | None, b: float | None, lower: Mapping[str, bool | None]) -> tuple[Cell, Cell, Cell]:
    """(B - A, relative change %, verdict). The verdict is "same" for equal values (inf = inf
    too), "better"/"worse" only where the metric's direction is known, else none."""
    if not (_number(a) and _number(b)):
        return None, None, "only in A" if b is None and a is not None else "only in B" if a is None else None
    assert a is not None
    assert b is not None
    if a == b:
        return 0.0 if math.isfinite(a) else None, 0.0 if math.isfinite(a) else None, "same"
    diff = b - a
    rel: Cell = 100.0 * diff / abs(a) if a != 0 and math.isfinite(a) and math.isfinite(b) else None
    direction = lower.get(key)
    verdict: Cell = None if direction is None else "better" if (diff < 0) == direction else "worse"
    return diff if math.isfinite(diff) else None, rel, verdict


def metrics_table(a: RunMetrics, b: RunMetrics, *, only_changed: bool = False) -> Table:
    keys = sorted(set(a.metrics) | set(b.metrics))
    lower = {**a.lower_is_better, **b.lower_is_better}
    rows, cells = [], []
    for key in keys:
        va, unit_a = a.metrics.get(key, (None, ""))
        vb, unit_b = b.metrics.get(key, (None, ""))
        diff, rel, verdict = _change(key, va, vb, lower)
        if only_changed and verdict == "same":
            continue
        rows.append(key)
        cells.append([unit_a or unit_b, va, vb, diff, rel, verdict])
    return Table(title=f"Metrics: A = {a.label}, B = {b.label}", row_labels=rows,
                 column_labels=["unit", "A", "B", "B - A", "change %", "verdict"], cells=cells, best=None,
                 precision=4, notes=[*mismatch_warnings(a, b), "verdict from the metric's direction (lower or "
                                     "higher is better) where known; none for counts and settings"])


def mismatch_warnings(a: RunMetrics, b: RunMetrics) -> list[str]:
    """What makes the comparison doubtful: runs of different logs, or of different kinds."""
    out = []
    if a.logs and b.logs and a.logs != b.logs:
        out.append(f"WARNING: A and B are runs of different logs (A: {', '.join(sorted(a.logs))}; "
                   f"B: {', '.join(sorted(b.logs))})")
    if a.kinds and b.kinds and a.kinds != b.kinds:
        out.append(f"WARNING: A and B are different kinds of run (A: {', '.join(sorted(a.kinds))}; "
                   f"B: {', '.join(sorted(b.kinds))}): few metrics in common")
    return out


def config_table(a: RunMetrics, b: RunMetrics) -> Table:
    """The configuration keys whose values differ (a key missing on one side shows as n/a)."""
    fa, fb = dict(a.config or {}), dict(b.config or {})
    keys = sorted(k for k in set(fa) | set(fb) if fa.get(k, _MISSING) != fb.get(k, _MISSING))
    notes = [] if a.config is not None and b.config is not None else ["a configuration is missing: not compared"]
    return Table(title="Configuration keys that differ", row_labels=keys, column_labels=["A", "B"],
                 cells=[[_text(fa.get(k, _MISSING)), _text(fb.get(k, _MISSING))] for k in keys], best=None,
                 notes=notes)


class _Missing:
    def __repr__(self) -> str:
        return "n/a"


_MISSING = _Missing()


def _text(v: Any) -> str:
    return "n/a" if v is _MISSING else str(v)
