"""Tables as data: a labelled grid of numbers or text cells. Pure (no IO): evaluation builds
them, results stores them, reports render them."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

Cell = float | int | str | None  # None or a str such as "Failed" marks a cell without a number


@dataclass
class Table:
    """A labelled grid: rows x columns of numbers or text cells ("Failed", "n/a")."""

    title: str
    row_labels: list[str]
    column_labels: list[str]
    cells: list[list[Cell]]
    unit: str = ""
    best: Literal["min", "max", None] = "min"  # which number per row is marked best, if any
    best_per: Literal["row", "column"] = "row"
    precision: int = 3
    notes: list[str] = field(default_factory=list)
