"""Table I layout: sequences as rows, methods as columns, APE RMSE per cell.

A cell is Failed when the method produced no trajectory, too few matched poses, or a
matched span shorter than a fraction of the reference (a method that tracked half the
sequence must not look good); it is "not run" when the method was never run on that
sequence (no result, no file): that is no verdict on the method. The mean row is over
the cells with a number, with the count noted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrnc_eval.tables import Table

FAILED = "Failed"
NOT_RUN = "not run"


@dataclass(frozen=True)
class Cell:
    """One APE cell of a comparison table (a value, or why there is none)."""

    value: float | None  # APE RMSE (m); None when failed
    reason: str = ""  # why it failed
    not_run: bool = False  # the method was never run on this sequence: no verdict

    @property
    def failed(self) -> bool:
        return self.value is None and not self.not_run


def judge(rmse: float, n: int, span_s: float, ref_span_s: float, *, min_matches: int,
          min_span_fraction: float) -> Cell:
    if n < min_matches:
        return Cell(None, f"{n} matched poses < {min_matches}")
    if ref_span_s > 0 and span_s < min_span_fraction * ref_span_s:
        return Cell(None, f"covers {span_s:.1f} s of {ref_span_s:.1f} s")
    return Cell(float(rmse))


def table_one(cells: dict[tuple[str, str], Cell], sequences: list[str], methods: list[str], *,
              title: str = "Absolute pose error (APE RMSE)", precision: int = 6) -> Table:
    grid: list[list[float | str | None]] = []
    notes: list[str] = []
    for seq in sequences:
        row: list[float | str | None] = []
        for m in methods:
            cell = cells.get((seq, m), Cell(None, not_run=True))
            row.append(NOT_RUN if cell.not_run else FAILED if cell.failed else cell.value)
            if cell.failed and cell.reason:
                notes.append(f"{seq} / {m}: Failed ({cell.reason})")
        grid.append(row)
    means: list[float | str | None] = []
    counts = []
    for k, m in enumerate(methods):
        vals = [v for r in grid if isinstance(v := r[k], float)]
        means.append(float(np.mean(vals)) if vals else FAILED)
        counts.append(f"{m} {len(vals)}/{len(sequences)}")
    notes.insert(0, "Mean over sequences with a number (not Failed, not 'not run'): " + ", ".join(counts))
    # A mean over fewer sequences is not comparable with a full one: name the best complete method too.
    complete = [(means[k], m) for k, m in enumerate(methods)
                if isinstance(means[k], float) and all(isinstance(r[k], float) for r in grid)]
    if complete and len(complete) < len(methods):
        best_mean, best_method = min(complete)
        notes.insert(1, "Lowest mean among methods without a Failed sequence: "
                        f"{best_method} ({best_mean:.{precision}f})")
    return Table(title=title, row_labels=list(sequences) + ["Mean"], column_labels=list(methods),
                 cells=grid + [means], unit="m", best="min", best_per="row", precision=precision, notes=notes)
