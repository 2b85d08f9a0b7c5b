"""Render one log's report (HTML, PDF) from its result objects; never recomputes.

Everything taken from a log (topic names, frame ids, messages, paths) reaches the page
through Jinja2's autoescaping; figures are our own SVG; tables come from render_table (which
escapes its cells)."""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from markupsafe import Markup

from mrnc_eval import __version__
from mrnc_eval.evaluation.config import GatesConfig
from mrnc_eval.reports.figures import control_figures, slam_figures
from mrnc_eval.reports.tables import render_table
from mrnc_eval.results import RunResult, atomic_write_text

TEMPLATES = Path(__file__).parent / "templates"
MAX_EVENTS = 60


@dataclass(frozen=True)
class Gate:
    label: str
    value: str
    limit: str
    status: str  # "pass" | "fail" | "na"


def _env():
    from jinja2 import Environment, FileSystemLoader, select_autoescape

    return Environment(loader=FileSystemLoader(TEMPLATES), autoescape=select_autoescape(["html", "j2"]))


def css() -> str:
    return (TEMPLATES / "base.css").read_text(encoding="utf-8")


def evaluate_gates(results: list[RunResult], gates: GatesConfig) -> list[Gate]:
    """Pass/fail cards: APE RMSE, funnel violations, saturation, safety stops."""
    def values(kind: str, name: str) -> list[float]:
        # control gates judge the deployed controller (RAID in simulation, the recorded run in replay)
        return [m.value for r in results if r.kind == kind for m in r.metrics
                if m.name == name and m.value is not None and not (isinstance(m.value, float) and math.isnan(m.value))
                and (kind != "control" or m.group.split("/")[1:2] in (["raid"], ["recorded"]))]

    out = []
    ape = values("slam", "ape_rmse_m")
    out.append(Gate("APE RMSE", f"{max(ape):.3f} m" if ape else "n/a", f"{gates.ape_rmse_max_m:g} m",
                    "na" if not ape else ("pass" if max(ape) <= gates.ape_rmse_max_m else "fail")))
    for label, name, limit, fmt in (("Funnel violations", "funnel_violations", gates.funnel_violations_max, "{:.0f}"),
                                    ("Saturation ratio", "saturation_ratio", gates.saturation_ratio_max, "{:.3f}"),
                                    ("Safety stops", "safety_stops", gates.safety_stops_max, "{:.0f}")):
        v = values("control", name)
        worst = max(v) if v else None
        out.append(Gate(label, fmt.format(worst) if v else "n/a", f"{limit:g}",
                        "na" if worst is None else ("pass" if worst <= limit else "fail")))
    return out


def _section(r: RunResult) -> dict[str, Any]:
    if r.kind == "slam":
        vals = {m.name: m.value for m in r.metrics}
        method = r.extra.get("method", "lio")
        summary = (f"Method {method}: {vals.get('sweeps_processed', 0)} sweeps processed, {vals.get('keyframes', 0)} "
                   f"keyframes, {vals.get('loop_closures', 0)} loop closures, {vals.get('degeneracy_events', 0)} "
                   f"degeneracy events, real-time factor {vals.get('rtf', float('nan')):.2f}")
        if "ape_rmse_m" in vals:
            summary += f"; APE RMSE {vals['ape_rmse_m']:.4f} m over {vals.get('ape_n', 0)} poses"
        if "ape_gnss_rmse_m" in vals:
            summary += f"; against GNSS (2-D) {vals['ape_gnss_rmse_m']:.3f} m"
        title, figures = "SLAM", slam_figures(r)
    else:
        mode = r.extra.get("mode", "")
        summary = f"Control chain, mode {mode}; controllers: " + ", ".join(r.extra.get("labels", {}).values())
        summary += (f"; saturation applies to the {r.extra.get('saturation_applies_to', 'total')} command, "
                    f"curvature {r.extra.get('curvature', 'standard')}")
        title, figures = "Control", control_figures(r)
        if not r.tables:  # replay: one column of per-side metrics
            pass
    tables = [Markup(render_table(t, "html")) for t in r.tables]
    if r.kind == "control" and not r.tables:
        tables.append(Markup(render_table(_metrics_table(r), "html")))
    events = r.events[:MAX_EVENTS]
    return {"title": title, "summary": summary, "warnings": r.warnings, "tables": tables,
            "figures": [(cap, Markup(svg)) for cap, svg in figures], "events": events,
            "events_more": max(0, len(r.events) - MAX_EVENTS)}


def _metrics_table(r: RunResult):
    from mrnc_eval.results import Table

    groups = sorted({m.group for m in r.metrics})
    names = sorted({m.name for m in r.metrics})
    by = {(m.group, m.name): m.value for m in r.metrics}
    return Table("Control metrics", names, groups, [[by.get((g, n)) for g in groups] for n in names], best=None, precision=4)


def render_html(results: list[RunResult], *, gates: GatesConfig, config_text: str, info: dict | None = None) -> str:
    first = results[0]
    return _env().get_template("report.html.j2").render(
        css=css(), log_id=first.log_id, log_path=first.log_path, tool_version=first.tool_version or __version__,
        config_hash=first.config_hash, created=dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        gates=evaluate_gates(results, gates), info=info, sections=[_section(r) for r in results],
        config_text=config_text)


def write_pdf(html: str, path: Path) -> str:
    """PDF via WeasyPrint; a plain matplotlib PDF that says it is a fallback otherwise.
    Returns "weasyprint" or "fallback"."""
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        import logging

        import weasyprint

        logging.getLogger("weasyprint").setLevel(logging.ERROR)  # SVG CSS properties it does not know
        logging.getLogger("fontTools").setLevel(logging.ERROR)
        weasyprint.HTML(string=html).write_pdf(tmp)
        engine = "weasyprint"
    except (ImportError, OSError) as err:
        _fallback_pdf(tmp, str(err))
        engine = "fallback"
    tmp.replace(path)
    return engine


def _fallback_pdf(path: Path, reason: str) -> None:
    from matplotlib.backends.backend_pdf import PdfPages
    from matplotlib.figure import Figure

    with PdfPages(path) as pdf:
        fig = Figure(figsize=(8.27, 11.69))
        fig.text(0.1, 0.9, "mrnc-eval report (fallback PDF)", fontsize=16)
        fig.text(0.1, 0.85, f"WeasyPrint unavailable: {reason[:200]}", fontsize=9)
        fig.text(0.1, 0.8, "Open the HTML report for the full content.", fontsize=9)
        pdf.savefig(fig)


def write_report(results: list[RunResult], out_dir: Path, *, gates: GatesConfig, config_text: str,
                 info: dict | None = None, pdf: bool = False) -> dict[str, Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    html = render_html(results, gates=gates, config_text=config_text, info=info)
    written = {"html": out_dir / "report.html"}
    atomic_write_text(written["html"], html)
    for r in results:
        for k, t in enumerate(r.tables):
            stem = f"{r.kind}_table{k + 1}"
            atomic_write_text(out_dir / f"{stem}.csv", render_table(t, "csv"))
            atomic_write_text(out_dir / f"{stem}.tex", render_table(t, "latex"))
    if pdf:
        written["pdf"] = out_dir / "report.pdf"
        write_pdf(html, written["pdf"])
    return written
