"""Render one log's report (HTML, PDF, CSV and LaTeX tables) from its result objects; never
recomputes.

Everything taken from a log (topic names, frame ids, messages, paths) reaches the page through
Jinja2's autoescaping; figures are our own SVG (log text inside them is escaped by matplotlib's
SVG writer); tables come from render_table, which escapes its cells."""

from __future__ import annotations

import datetime as dt
import logging
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from markupsafe import Markup

from mrnc_eval import __version__
from mrnc_eval.evaluation.config import GatesConfig
from mrnc_eval.outputs import claim_output, output_file, write_output
from mrnc_eval.reports.gates import Gate as Gate  # re-exported (reports/gates.py: the gates without the report stack)
from mrnc_eval.reports.gates import evaluate_gates as evaluate_gates
from mrnc_eval.results import Metric, RunResult, safe_name
from mrnc_eval.schema import control as C
from mrnc_eval.schema import info as I
from mrnc_eval.schema import slam as S
from mrnc_eval.tables import Cell, Table

TEMPLATES = Path(__file__).parent / "templates"
MAX_EVENTS = 60  # rows of the events table; the rest is counted

SLAM_KEYS = (  # (label, metric name) of the SLAM key-number table
    ("APE RMSE, online (m)", "ape_online_rmse_m"), ("APE RMSE, smoothed (m)", "ape_rmse_m"),
    ("APE mean, smoothed (m)", "ape_mean_m"), ("APE max, smoothed (m)", "ape_max_m"),
    ("end drift, online (m)", "end_drift_online_m"), ("end drift, smoothed (m)", "end_drift_m"),
    ("APE vs GNSS, 2-D RMSE (m)", "ape_gnss_rmse_m"), ("matched poses", "ape_n"),
    ("real-time factor (at the mapping rate below)", "rtf"), ("mapping rate (Hz)", "mapping_rate_hz"),
    ("sweeps processed", "sweeps_processed"),
    ("keyframes", "keyframes"), ("loop closures", "loop_closures"), ("degeneracy events", "degeneracy_events"),
    ("IMU time offset (s)", "imu_time_offset_s"), ("mean map entropy (nats)", "map_entropy"),
    ("mean plane variance (m^2)", "map_plane_variance_m2"))
LIO_ONLY_KEYS = ("keyframes", "loop_closures", "degeneracy_events", "imu_time_offset_s")  # no meaning for the peer
SLAM_DEFINITIONS = {  # metric that must be present -> its definition (only what the section shows is defined)
    "ape_online_rmse_m": "Online: each sweep's pose as estimated when it was processed (what a real-time system "
                         "has). Smoothed: each sweep re-anchored after the run to its final, loop-corrected keyframe "
                         "(trajectory.tum).",
    "map_entropy": "Mean map entropy: mean over map points of 0.5 ln det(2 pi e Sigma), Sigma the covariance of the "
                   "map points within the radius slam.map_quality.radius_m; lower is a sharper map. Mean plane "
                   "variance: mean smallest eigenvalue of the same Sigma (m^2). Map = union of the keyframe feature "
                   "clouds in their final poses.",
    "imu_time_offset_s": "IMU time offset: the IMU clock's lag behind the LiDAR's (positive: IMU stamps late), from "
                         "correlating the LiDAR odometry's rotation rate with the gyro, after slam.imu.time_offset_s "
                         "was applied.",
    "ape_gnss_rmse_m": "APE vs GNSS: the 2-D error of the GNSS antenna's estimated track against the fixes (ENU), "
                       "after a yaw + translation alignment; it includes the GNSS error itself.",
}
PEER_DEFINITION = ("kiss-icp (the peer, configured as its own runner): scan-to-map odometry without keyframes or "
                   "loop closure, so trajectory.tum and trajectory_online.tum hold the same poses and online equals "
                   "smoothed. Deskew {deskew}.")
CONTROL_ROWS = (  # Table II rows for a replay (one column per side and the path)
    ("settling time (s)", "settling_time_s"), ("overshoot (%)", "overshoot_pct"),
    ("steady-state error (m/s)", "steady_state_error_mps"), ("RMS error (m/s)", "rms_error_mps"),
    ("max |error| (m/s)", "max_abs_error_mps"), ("IAE", "iae"), ("funnel violations", "funnel_violations"),
    ("max |e|/o", "max_e_over_o"), ("saturation ratio", "saturation_ratio"),
    ("max |command| (RPM)", "max_abs_command_rpm"), ("safety stops", "safety_stops"),
    ("cross-track RMS (m)", "cross_track_rms_m"), ("cross-track max (m)", "cross_track_max_m"),
    ("heading error RMS (rad)", "heading_error_rms_rad"), ("final position error (m)", "final_position_error_m"))


def environment():
    from jinja2 import Environment, FileSystemLoader, StrictUndefined, select_autoescape

    from mrnc_eval.text import html_text

    # finalize: every value printed from log content loses its control characters (one sanitiser)
    return Environment(loader=FileSystemLoader(TEMPLATES), autoescape=select_autoescape(["html", "j2"]),
                       undefined=StrictUndefined, finalize=html_text)


def css() -> Markup:
    """Our own style sheet, trusted: autoescaping would turn its quotes into entities, which a
    <style> element does not decode."""
    return Markup((TEMPLATES / "base.css").read_text(encoding="utf-8"))


CARD_KIND = {"APE RMSE": "slam", "Funnel violations": "control", "Saturation ratio": "control",
             "Safety stops": "control"}


def report_cards(results: list[RunResult], gates: GatesConfig, extra: Sequence[Gate] = ()) -> list[Gate]:
    """The cards a report shows: the gates of the kinds of run it holds (no control cards on a
    SLAM-only report; JUnit keeps every gate, skipped), then `extra` (cards other modules add,
    e.g. counts of dropped input, in the same Gate form)."""
    kinds = {r.kind for r in results}
    return [g for g in evaluate_gates(results, gates) if CARD_KIND.get(g.label.split(" (")[0], "") in kinds
            or g.status != "na"] + list(extra)


def info_of(results: list[RunResult]) -> dict[str, Any] | None:
    """The `info` summary: a result of kind "info", or extra["info"] of any result."""
    for r in results:
        if isinstance(r.extra.get(I.INFO), dict):
            return r.extra[I.INFO]
    return None


def _key_table(title: str, rows: list[tuple[str, Any]]) -> Table:
    return Table(title, [label for label, _ in rows], ["value"], [[v] for _, v in rows], best=None, precision=4)


def _warmup_text(r: RunResult) -> str:
    """The one-off cost paid before the timed loop (lio: matching's and the ICP's first calls), said apart from
    the per-sweep statistics; nothing when the method had none."""
    total = r.extra.get(S.WARMUP_TOTAL_MS)
    if not total:
        return ""
    return (f", after a warm-up of {total:.0f} ms before the timed loop (the first calls of matching and "
            "of the loop-closure ICP; in neither the per-stage statistics nor the "
            "processing time)")


def slam_definitions(r: RunResult) -> list[str]:
    """The definitions a SLAM section needs: only of the numbers it shows, and the peer's own
    (kiss-icp has no keyframes, loop closure or IMU, so no LIO text in its section)."""
    method = str(r.extra.get(S.METHOD, "lio"))
    shown = {m.name for m in r.metrics}
    out = []
    if method != "lio":
        deskew = r.extra.get(S.DESKEW)
        out.append(PEER_DEFINITION.format(deskew="on" if deskew else "off" if deskew is not None else "unknown"))
    for name, text in SLAM_DEFINITIONS.items():
        if name in shown and (method == "lio" or name != "ape_online_rmse_m"):
            out.append(text)
    return out


def _slam_section(r: RunResult) -> dict[str, Any]:
    from mrnc_eval.reports.figures import slam_figures

    method = str(r.extra.get(S.METHOD, "lio"))
    vals = {m.name: m.value for m in r.metrics}
    if method == "lio":
        keys = [(label, vals[name]) for label, name in SLAM_KEYS if name in vals]
    else:  # the peer: one trajectory (online = smoothed), no keyframes, loops or IMU
        keys = [(label.replace(", smoothed", ""), vals[name]) for label, name in SLAM_KEYS if name in vals
                and name not in LIO_ONLY_KEYS and name not in ("ape_online_rmse_m", "end_drift_online_m")]
    timing = {stage: t for stage, t in r.extra.get(S.TIMING_MS, {}).items()  # the peer has no graph or loop stage
              if method == "lio" or any(t.get(k) for k in ("mean", "p95", "max"))}
    stats = ("mean", "p95", "max")
    timing_table = Table("Per-stage timing", list(timing), list(stats), [[t.get(k) for k in stats]
                                                                         for t in timing.values()],
                         unit="ms per sweep, first sweep excluded", best=None, precision=1)
    summary = (f"Method {method}; log of {r.extra.get(S.LOG_DURATION_S, float('nan')):.1f} s "
               f"processed in {r.extra.get(S.WALL_S, float('nan')):.1f} s (first sweep "
               f"{r.extra.get(S.FIRST_SWEEP_MS, float('nan')):.0f} ms){_warmup_text(r)}; "
               f"{r.extra.get(S.MAPPING_RATE, '')}.")
    tables = [_key_table("SLAM key numbers", keys)] + ([timing_table] if timing else []) + r.tables
    return {"title": f"SLAM ({r.extra[S.METHOD]})" if r.extra.get(S.METHOD) else "SLAM", "summary": summary,
            "definitions": slam_definitions(r), "tables": tables, "figures": slam_figures(r, timing=timing),
            "quiet_events": "no loop closures, no degeneracy" if method == "lio" else ""}


def _control_section(r: RunResult) -> dict[str, Any]:
    from mrnc_eval.reports.figures import control_figures

    labels = r.extra.get(C.LABELS, {})
    summary = (f"Control chain, mode {r.extra.get(C.MODE, '?')}; controllers: "
               + ", ".join(labels.get(c, c) for c in r.extra.get(C.CONTROLLERS, []))
               + f". Saturation applies to the {r.extra.get(C.SATURATION_APPLIES_TO, 'total')} command; "
               f"pure-pursuit curvature {r.extra.get(C.CURVATURE, 'standard')}.")
    if r.extra.get(C.REPLAY) and r.extra.get(C.DEFINITIONS):  # what the replay's references are
        summary += " " + r.extra[C.DEFINITIONS][0]
    title = "Control: wheel-speed tracking (no path)" if r.extra.get(C.REPLAY) == "wheel_speed" else "Control"
    return {"title": title, "summary": summary, "definitions": [], "tables": report_tables(r),
            "figures": control_figures(r), "quiet_events": ""}


def report_tables(r: RunResult) -> list[Table]:
    """The paper-layout tables of a result: its own, or for a control replay (which has none)
    the Table II layout of its metrics."""
    if r.kind == "control" and not r.tables and r.metrics:
        return [_replay_table(r)]
    return list(r.tables)


def _replay_table(r: RunResult) -> Table:
    """Table II layout for a replay: rows = metrics, columns = the groups of the result."""
    groups = sorted({m.group for m in r.metrics}, key=lambda g: (g.endswith("/path"), g))
    by: dict[tuple[str, str], Metric] = {(m.group, m.name): m for m in r.metrics}
    rows = [(label, name) for label, name in CONTROL_ROWS if any((g, name) in by for g in groups)]
    values = [[(by[(g, name)].value if (g, name) in by else None) for g in groups] for _label, name in rows]
    cells: list[list[Cell]] = [[("not settled" if isinstance(c, float) and math.isinf(c)  # as the legend says
                                 else None if isinstance(c, float) and math.isnan(c) else c) for c in row]
                               for row in values]
    what = " (wheel-speed tracking, no path)" if r.extra.get(C.REPLAY) == "wheel_speed" else ""
    return Table(f"Table II layout: control performance of the recorded run{what}", [label for label, _ in rows],
                 [g.split("/", 1)[-1].replace("/", " ") for g in groups], cells, best=None, precision=3)


def _section(r: RunResult) -> dict[str, Any]:
    from mrnc_eval.reports.tables import render_table

    section = _slam_section(r) if r.kind == "slam" else _control_section(r)
    events = sorted(r.events, key=lambda e: e.t_s)
    counts: dict[str, int] = {}
    for e in events:
        counts[e.kind] = counts.get(e.kind, 0) + 1
    section.update(kind=r.kind, warnings=r.warnings, config_hash=r.config_hash, events=events[:MAX_EVENTS],
                   event_counts=sorted(counts.items()), events_more=max(0, len(events) - MAX_EVENTS),
                   tables=[Markup(render_table(t, "html")) for t in section["tables"]],
                   figures=[(cap, Markup(svg)) for cap, svg in section["figures"]])
    return section


@dataclass(frozen=True)
class ConfigDiff:
    """One configuration of a report: its hash, the runs that used it and the keys it sets
    away from the defaults (key, value, default)."""

    config_hash: str
    used_by: list[str]
    changed: list[tuple[str, str, str]]
    text: str  # the full YAML, shown only in the appendix; "" when no config.yaml was found


def config_differences(config_text: str) -> list[tuple[str, str, str]]:
    """(key, value, default) of every key a config.yaml sets away from this mrnc-eval's defaults."""
    from mrnc_eval.config import Config, as_dict, load_yaml
    from mrnc_eval.reports.compare import flatten

    if not config_text.strip():
        return []
    loaded = load_yaml(config_text, "config.yaml")
    defaults = flatten(as_dict(Config()))
    given = flatten(loaded if isinstance(loaded, Mapping) else {})

    def shown(v: Any) -> str:
        return "(not set)" if v is _UNSET else str(list(v) if isinstance(v, tuple) else v)

    # keys of the file only: a key the file lacks was added to mrnc-eval after the run (its default
    # did not exist then), not set by anyone; a key today's defaults lack shows "(not set)" as default
    return [(k, shown(given[k]), shown(defaults.get(k, _UNSET))) for k in sorted(given)
            if _comparable(given[k]) != _comparable(defaults.get(k, _UNSET))]


_UNSET = object()


def _comparable(v: Any) -> Any:
    return list(v) if isinstance(v, tuple) else v


def _config_diffs(results: list[RunResult], configs: Mapping[str, str]) -> list[ConfigDiff]:
    """One entry per distinct configuration hash, in the order of the report's sections."""
    out: list[ConfigDiff] = []
    for h, text in configs.items():
        used = [_run_label(r) for r in results if r.config_hash == h]
        out.append(ConfigDiff(h, used, config_differences(text), text))
    return out


def _run_label(r: RunResult) -> str:
    """"SLAM lio", "control replay": which run of the report a configuration belongs to."""
    what = r.extra.get(S.METHOD) if r.kind == "slam" else r.extra.get(C.MODE)
    return f"{'SLAM' if r.kind == 'slam' else r.kind} {what}" if what else r.kind


def render_html(results: list[RunResult], *, gates: GatesConfig, config_text: str,
                configs: Mapping[str, str] | None = None, appendix_config: bool = False,
                cards: Sequence[Gate] = ()) -> str:
    """The report page. `configs` maps each configuration hash of the results to its YAML
    (default: `config_text` for the first hash); the report lists every hash and the keys each
    sets away from the defaults; the full YAML only with `appendix_config`. `cards` are further
    cards shown after the gates (a hook for other modules)."""
    first = results[0]
    hashes = list(dict.fromkeys(r.config_hash for r in results if r.config_hash))
    if configs is None:
        configs = {hashes[0] if hashes else "": config_text}
    info = info_of(results)
    findings = [w for r in results if r.kind == "info" for w in r.warnings]
    used = {role: topic for r in results for role, topic in (r.extra.get(S.ROLES) or {}).items()}
    return environment().get_template("report.html.j2").render(
        css=css(), log_id=first.log_id, log_path=first.log_path, tool_version=first.tool_version or __version__,
        config_hashes=[(h, [_run_label(r) for r in results if r.config_hash == h]) for h in hashes],
        created=dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        gates=report_cards(results, gates, cards), info=info, notes=findings, used_roles=used,
        sections=[_section(r) for r in results if r.kind in ("slam", "control")],
        configs=_config_diffs(results, configs), appendix_config=appendix_config)


def pdf_engine() -> object:
    """The weasyprint module, or MissingExtra naming the pdf extra (or the Pango libraries) when it
    cannot load: a PDF is never replaced by a placeholder. Called before anything is written."""
    from mrnc_eval.errors import MissingExtra

    try:
        import weasyprint
    except ImportError as err:
        raise MissingExtra(f"a PDF needs the pdf extra (WeasyPrint: {err}): pip install 'mrnc-eval[pdf]'; "
                           "or leave out --pdf (report.html is self-contained)") from None
    except OSError as err:
        if err.errno is not None:
            raise
        raise MissingExtra(f"WeasyPrint cannot load its libraries ({err}): install Pango (scripts/setup.sh) "
                           "or leave out --pdf") from None
    return weasyprint


def write_pdf(html: str, path: Path, *, force: bool = False) -> str:
    """PDF via WeasyPrint from the same HTML (print CSS), under the overwrite rule. Returns the
    engine used; without WeasyPrint (or Pango) MissingExtra, and nothing is written."""
    engine: Any = pdf_engine()
    with output_file(path, force=force) as tmp:
        logging.getLogger("weasyprint").setLevel(logging.ERROR)  # SVG CSS properties it does not know
        logging.getLogger("fontTools").setLevel(logging.ERROR)
        engine.HTML(string=html).write_pdf(tmp)
    return "weasyprint"


_ROMAN = {"I": 1, "II": 2, "III": 3, "IV": 4, "V": 5}


def table_files(results: list[RunResult]) -> dict[str, Table]:
    """File stem -> table, each named after the paper table it lays out: slam_table1 (Table I,
    sequences x methods: one file with every method of the report), control_table2 (Table II)."""
    named: dict[str, list[Table]] = {}
    for r in results:
        for k, table in enumerate(report_tables(r)):
            numeral = re.match(r"Table (I{1,3}|IV|V)\b", table.title)
            number = _ROMAN[numeral.group(1)] if numeral else 1 if r.kind == "slam" and k == 0 else k + 1
            named.setdefault(safe_name(f"{r.kind}_table{number}"), []).append(table)
    out: dict[str, Table] = {}
    for stem, tables in named.items():
        if stem.startswith("slam_table1") and len(tables) > 1:
            out[stem] = merge_columns(tables)
        else:
            out.update({stem if k == 0 else f"{stem}_{k + 1}": t for k, t in enumerate(tables)})
    return out


def merge_columns(tables: list[Table]) -> Table:
    """Tables of the same rows (sequences) side by side: the columns (methods) of all, a "Mean"
    row kept last."""
    rows = list(dict.fromkeys(label for t in tables for label in t.row_labels))
    rows.sort(key=lambda label: label.lower().startswith("mean"))
    columns: list[str] = []
    cells: list[list[Cell]] = [[] for _ in rows]
    for t in tables:
        by_row = dict(zip(t.row_labels, t.cells, strict=False))
        for c, label in enumerate(t.column_labels):
            columns.append(label)
            for i, row in enumerate(rows):
                cells[i].append(by_row[row][c] if row in by_row and c < len(by_row[row]) else None)
    first = tables[0]
    return Table(first.title, rows, columns, cells, unit=first.unit, best=first.best, best_per=first.best_per,
                 precision=first.precision, notes=list(dict.fromkeys(n for t in tables for n in t.notes)))


def write_report(results: list[RunResult], out_dir: Path, *, gates: GatesConfig, config_text: str,
                 pdf: bool = False, force: bool = False, configs: Mapping[str, str] | None = None,
                 appendix_config: bool = False, cards: Sequence[Gate] = ()) -> dict[str, Path]:
    """report.html (+ report.pdf) and every table as CSV and LaTeX, each written atomically under
    the one overwrite rule (mrnc_eval/outputs.py): all claimed before the first is written
    (`configs`, `appendix_config`, `cards`: see render_html)."""
    from mrnc_eval.reports.tables import render_table

    if pdf:
        pdf_engine()  # before anything is written: no report half made when the PDF cannot be
    html = render_html(results, gates=gates, config_text=config_text, configs=configs,
                       appendix_config=appendix_config, cards=cards)
    texts = {"html": (out_dir / "report.html", html)}
    for stem, table in table_files(results).items():
        for fmt, suffix in (("csv", ".csv"), ("latex", ".tex")):
            texts[f"{stem}{suffix}"] = (out_dir / f"{stem}{suffix}", render_table(table, fmt))
    for path in [p for p, _ in texts.values()] + ([out_dir / "report.pdf"] if pdf else []):
        claim_output(path, force=force)
    written = {}
    for key, (path, text) in texts.items():
        written[key] = write_output(path, text, force=force)
    if pdf:
        written["pdf"] = out_dir / "report.pdf"
        write_pdf(html, written["pdf"], force=force)
    return written
