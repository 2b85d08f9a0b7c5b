"""Render a tables.Table as Markdown, LaTeX (booktabs), CSV or HTML (escaped).

Numbers are printed with the table's precision; the best number per row (or column) is
bold; text cells such as "Failed" pass through (escaped).
"""

from __future__ import annotations

import io
import math
import re
from typing import TypeGuard

from mrnc_eval.errors import UnknownName
from mrnc_eval.tables import Cell, Table

FORMATS = ("markdown", "latex", "csv", "html")
SUFFIX_FORMAT = {".md": "markdown", ".tex": "latex", ".csv": "csv", ".html": "html", ".htm": "html"}


def is_number(c: object) -> TypeGuard[float | int]:
    """A finite int or float (not a bool): what tables compare and gates judge."""
    return isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c)


def best_cells(table: Table) -> set[tuple[int, int]]:
    """(row, column) of the best number per row/column (ties all marked)."""
    if table.best is None:
        return set()
    pick = min if table.best == "min" else max
    out: set[tuple[int, int]] = set()
    rows, cols = len(table.cells), len(table.column_labels)
    lines = ([[(r, c) for c in range(cols)] for r in range(rows)] if table.best_per == "row"
             else [[(r, c) for r in range(rows)] for c in range(cols)])
    for line in lines:
        nums = [(cell, (r, c)) for r, c in line
                if c < len(table.cells[r]) and is_number(cell := table.cells[r][c])]
        if len(nums) < 2:
            continue
        target = round(pick(v for v, _ in nums), table.precision)
        out.update(pos for v, pos in nums if round(v, table.precision) == target)
    return out


def fmt_cell(c: Cell, precision: int) -> str:
    if c is None:
        return "–"  # noqa: RUF001 - an en dash marks a missing value in printed tables
    if isinstance(c, bool):
        return "yes" if c else "no"
    if isinstance(c, int):
        return str(c)
    if isinstance(c, float):
        return "nan" if math.isnan(c) else f"{c:.{precision}f}"
    return str(c)


def render_table(table: Table, fmt: str = "markdown") -> str:
    if fmt not in FORMATS:
        raise UnknownName("table format", fmt, FORMATS)
    return {"markdown": _markdown, "latex": _latex, "csv": _csv, "html": _html}[fmt](table)


def _grid(table: Table, bold) -> list[list[str]]:
    best = best_cells(table)
    return [[bold(fmt_cell(c, table.precision)) if (r, k) in best else fmt_cell(c, table.precision)
             for k, c in enumerate(row)] for r, row in enumerate(table.cells)]


def _title(table: Table) -> str:
    return table.title + (f" ({table.unit})" if table.unit else "")


def _markdown(table: Table) -> str:
    esc = lambda s: s.replace("|", "\\|")  # noqa: E731
    grid = _grid(table, lambda s: f"**{s}**")
    lines = [f"**{esc(_title(table))}**", "", "| " + " | ".join([""] + [esc(c) for c in table.column_labels]) + " |",
             "|" + "---|" * (len(table.column_labels) + 1)]
    lines += ["| " + " | ".join([esc(label)] + [esc(c) for c in row]) + " |"
              for label, row in zip(table.row_labels, grid, strict=False)]
    lines += [""] + [f"_{esc(n)}_" for n in table.notes]
    return "\n".join(lines).rstrip() + "\n"


_LATEX_SPECIAL = {"&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_", "{": r"\{", "}": r"\}",
                  "~": r"\textasciitilde{}", "^": r"\textasciicircum{}", "\\": r"\textbackslash{}"}


def latex_escape(s: str) -> str:
    return "".join(_LATEX_SPECIAL.get(ch, ch) for ch in s)


def _latex(table: Table) -> str:
    grid = _grid(table, lambda s: f"\\textbf{{{s}}}")
    # escape text, keep our own \textbf
    def cell(s: str) -> str:
        if s.startswith("\\textbf{"):
            return "\\textbf{" + latex_escape(s[8:-1]) + "}"
        return latex_escape(s)

    cols = "l" + "r" * len(table.column_labels)
    out = ["\\begin{table}[t]", "\\centering", f"\\caption{{{latex_escape(_title(table))}}}",
           f"\\begin{{tabular}}{{{cols}}}", "\\toprule",
           " & ".join([""] + [latex_escape(c) for c in table.column_labels]) + " \\\\", "\\midrule"]
    for k, (label, row) in enumerate(zip(table.row_labels, grid, strict=False)):
        if label.lower().startswith("mean") and k == len(grid) - 1:
            out.append("\\midrule")
        out.append(" & ".join([latex_escape(label)] + [cell(c) for c in row]) + " \\\\")
    out += ["\\bottomrule", "\\end{tabular}"]
    for n in table.notes:
        out.append(f"\\par\\footnotesize {latex_escape(n)}")
    out.append("\\end{table}")
    return "\n".join(out) + "\n"


# decimals by unit (the one in a row label's parentheses, else the table's): a resolution finer
# than the data, coarser than float32 noise (9.900000095367432 -> 9.9); JSON keeps full precision
UNIT_DECIMALS = {"m": 4, "mm": 1, "s": 3, "ms": 1, "m/s": 4, "rad/s": 4, "rpm": 2, "%": 2, "deg": 3, "rad": 5,
                 "m/m": 5, "deg/m": 5, "hz": 2}


def decimals_for(label: str, table: Table) -> int:
    """Decimals for the numbers of a row: by the unit in its label ("Settling time (s)"), else
    by the table's unit, else the table's precision."""
    match = re.search(r"\(([^()]*)\)\s*$", label)
    for unit in (match.group(1) if match else "", table.unit):
        if unit.strip().lower() in UNIT_DECIMALS:
            return UNIT_DECIMALS[unit.strip().lower()]
    return table.precision


def _csv(table: Table) -> str:
    import csv  # here: `slam` imports this module for is_number alone

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([_title(table)] + table.column_labels)
    for label, row in zip(table.row_labels, table.cells, strict=False):
        places = decimals_for(label, table)
        w.writerow([label] + [("" if c is None else (repr(round(c, places)) if isinstance(c, float) else c))
                              for c in row])
    return buf.getvalue()


def _html(table: Table) -> str:
    import html  # here: `slam` imports this module for is_number alone (html.entities: ~2 ms)

    e = html.escape
    best = best_cells(table)
    head = "".join(f"<th>{e(c)}</th>" for c in table.column_labels)
    rows = []
    for r, (label, row) in enumerate(zip(table.row_labels, table.cells, strict=False)):
        tds = []
        for k, c in enumerate(row):
            text = e(fmt_cell(c, table.precision))
            cls = ' class="failed"' if isinstance(c, str) else ""
            tds.append(f"<td{cls}><strong>{text}</strong></td>" if (r, k) in best else f"<td{cls}>{text}</td>")
        rows.append(f"<tr><th scope=\"row\">{e(label)}</th>{''.join(tds)}</tr>")
    notes = "".join(f"<p class=\"note\">{e(n)}</p>" for n in table.notes)
    return (f"<table class=\"results\"><caption>{e(_title(table))}</caption><thead><tr><th></th>{head}</tr></thead>"
            f"<tbody>{''.join(rows)}</tbody></table>{notes}")
