"""The night index (one row per log) and the trends page (metrics across nights)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from markupsafe import Markup

from mrnc_eval import __version__
from mrnc_eval.history import RunStatus
from mrnc_eval.reports.figures import new_figure, svg
from mrnc_eval.reports.render import css, environment

if TYPE_CHECKING:
    from mrnc_eval.history import Regression

MAX_LOGS_PER_TREND = 12  # more lines than this are unreadable: the worst latest values are drawn


@dataclass(frozen=True)
class IndexRow:
    """One log's row in a night's index: status, the worst value per column, links."""

    log_id: str
    log_path: str
    status: RunStatus
    error: str
    cells: tuple[str, ...]  # formatted; an en dash when not measured
    report: str  # relative link to the HTML report, "" when none
    pdf: str
    gates_failed: tuple[str, ...]


def render_index(night: str, rows: list[IndexRow], columns: list[str]) -> str:
    return environment().get_template("index.html.j2").render(
        css=css(), night=night, tool_version=__version__, rows=rows, columns=columns,
        failed=sum(r.status != "ok" for r in rows), gate_failures=sum(bool(r.gates_failed) for r in rows))


UNIT_SUFFIXES = (("_mps", "m/s"), ("_pct", "%"), ("_rpm", "RPM"), ("_hz", "Hz"), ("_ms", "ms"), ("_m2", "m^2"),
                 ("_deg", "deg"), ("_rad", "rad"), ("_m", "m"), ("_s", "s"))


def metric_label(key: str) -> str:
    """A history key as the report names it, with its unit: "slam/ape/ape_rmse_m" -> "APE RMSE,
    smoothed (m)", "control/recorded/left/rms_error_mps" -> "RMS error (m/s), recorded left"."""
    from mrnc_eval.reports.render import CONTROL_ROWS, SLAM_KEYS

    group, _, name = key.rpartition("/")
    known = {n: label for label, n in (*SLAM_KEYS, *CONTROL_ROWS)} | {"rtf": "real-time factor (log time / wall time)"}
    if name in known:
        label = known[name]
    elif name.startswith("ms_per_sweep_"):
        label = f"{name.removeprefix('ms_per_sweep_')} time per sweep (ms)"
    else:
        unit = next((u for suffix, u in UNIT_SUFFIXES if name.endswith(suffix)), "")
        words = name.removesuffix(next((s_ for s_, u in UNIT_SUFFIXES if u == unit), "")) if unit else name
        label = words.replace("_", " ") + (f" ({unit})" if unit else "")
    where = " ".join(p for p in group.split("/") if p not in ("slam", "control", "ape", "timing", ""))
    return label + (f", {where}" if where else "")


def render_trends(nights: list[str], data: dict[str, dict[str, dict[str, float]]],
                  regressions: dict[str, list[Regression]], window: int, tolerance: float) -> str:
    """data: metric -> log id -> night -> value; regressions: metric -> flagged latest values
    (circled in red on the plot)."""
    figures = []
    for metric, per_log in data.items():
        fig, axes = new_figure(7.0, 2.8)
        ax = axes[0, 0]
        x_of = {n: k for k, n in enumerate(nights)}
        shown = sorted(per_log, key=lambda log: per_log[log][max(per_log[log])], reverse=True)[:MAX_LOGS_PER_TREND]
        for log_id in sorted(shown):
            by_night = per_log[log_id]
            xs = sorted(by_night, key=x_of.__getitem__)
            ax.plot([x_of[n] for n in xs], [by_night[n] for n in xs], marker="o", ms=3, lw=1, label=log_id)
        for reg in regressions.get(metric, []):
            ax.plot([x_of[reg.night]], [reg.value], "o", ms=9, mfc="none", mec="tab:red", mew=1.5)
        ax.set_xticks(range(len(nights)), nights, rotation=30, ha="right", fontsize="small")
        ax.set_xlim(-0.5, len(nights) - 0.5)
        ax.set_title(metric_label(metric) + ("" if len(shown) == len(per_log)
                                             else f" ({len(shown)} of {len(per_log)} logs)"))
        ax.grid(alpha=0.3)
        ax.legend(fontsize="x-small", loc="center left", bbox_to_anchor=(1.01, 0.5))
        figures.append((Markup("{} <code>{}</code>").format(metric_label(metric), metric), Markup(svg(fig))))
    return environment().get_template("trends.html.j2").render(
        css=css(), nights=nights, figures=figures, window=window,
        regressions=[str(r) for found in regressions.values() for r in found],
        tolerance_pct=round(tolerance * 100), tool_version=__version__)
