"""Report figures with matplotlib's object API (Figure + FigureCanvasSVG, no pyplot state),
returned as inline SVG. Long series are decimated for drawing only; statistics never are."""

from __future__ import annotations

import io
import itertools
import re

import numpy as np

from mrnc_eval.results import RunResult
from mrnc_eval.schema import control as C
from mrnc_eval.schema import slam as S

U_MAX_RPM = 1250.0  # pump command limit drawn on the effort plot, RPM
MAX_POINTS = 4000  # per line
FUNNEL_CONTROLLERS = ("raid", "recorded")  # the funnel o(t) bounds RAID's error (and the deployed run's)
EVENT_COLOURS = {"loop_closure": "tab:green", "degeneracy": "tab:red", "safety_stop": "tab:red"}

_FIGURE_IDS = itertools.count(1)
_ID = re.compile(r'id="([^"]+)"')
_REF = re.compile(r'(href="#|url\(#)([^")]+)')
_METADATA = re.compile(r"<metadata>.*?</metadata>\s*", re.S)


def svg(fig) -> str:
    """Inline SVG with text as text and ids made unique per figure: several matplotlib SVGs in
    one page would otherwise share ids such as "patch_1" and pick up each other's clip paths."""
    import matplotlib
    from matplotlib.backends.backend_svg import FigureCanvasSVG

    buf = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "mrnc-eval"}):
        FigureCanvasSVG(fig).print_svg(buf, metadata={"Date": None})
    text = buf.getvalue()
    text = text[text.index("<svg"):]  # drop the XML prolog and doctype: the SVG is inlined in HTML
    text = _METADATA.sub("", text, count=1)  # RDF block naming matplotlib: no use in a report
    prefix = f"f{next(_FIGURE_IDS)}-"
    text = _ID.sub(lambda m: f'id="{prefix}{m.group(1)}"', text)
    return _REF.sub(lambda m: f"{m.group(1)}{prefix}{m.group(2)}", text)


def new_figure(w: float = 7.0, h: float = 3.2, rows: int = 1, cols: int = 1, sharex: bool = False):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h), layout="constrained")
    return fig, fig.subplots(rows, cols, squeeze=False, sharex=sharex)


def decimate(*arrays: np.ndarray) -> list[np.ndarray]:
    """Every k-th sample so that at most MAX_POINTS remain (same k for all arrays)."""
    n = min(len(a) for a in arrays)
    step = max(1, -(-n // MAX_POINTS))
    return [np.asarray(a[:n])[::step] for a in arrays]


def draw_error_path(fig, ax, ref_xyz: np.ndarray, est_xyz: np.ndarray, err: np.ndarray, *, unit: str = "m",
                    est_label: str = "estimate (SE(3) aligned)", ref_label: str = "ground truth",
                    title: str = "Trajectory in the plane, coloured by APE",
                    overlays: list[tuple[np.ndarray, str, str]] | None = None, axes: str = "xy",
                    legend_below: bool = False) -> None:
    """The estimate's path in the plane of `axes` (two of x, y, z: evo's --plot_mode) coloured
    by its error, the reference dashed beside it, `overlays` as plain lines (decimated for
    drawing). One implementation for SLAM reports and `ape --plot` (`legend_below`: the legend
    under the axes, where it covers no path and the constrained layout makes room for it)."""
    a, b = ("xyz".index(axes[0]), "xyz".index(axes[1]))
    ref, est, e = decimate(ref_xyz, est_xyz, err)
    ax.plot(ref[:, a], ref[:, b], color="0.55", lw=1.0, ls="--", label=ref_label)
    for xyz, label, colour in overlays or ():  # further paths as lines (e.g. the online estimate)
        line, = decimate(xyz)
        ax.plot(line[:, a], line[:, b], color=colour, lw=0.8, label=label)
    sc = ax.scatter(est[:, a], est[:, b], c=e, s=6, cmap="viridis", label=est_label)
    ax.plot(est[:1, a], est[:1, b], "k^", ms=7, label="start")
    fig.colorbar(sc, ax=ax, label=f"APE ({unit})" if unit else "APE")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel=f"{axes[0]} (m)", ylabel=f"{axes[1]} (m)", title=title)
    if legend_below:
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), fontsize="small", ncols=3, frameon=False)
    else:
        ax.legend(loc="best", fontsize="small")


TITLE_CHARS_PER_INCH = 9  # characters of a 12 pt title per inch of axes width (DejaVu Sans, with margin)


def wrapped(text: str, width_in: float) -> str:
    """`text` broken into lines that fit `width_in` inches at title size: after spaces, and
    inside file names and run folders after / - _; a piece longer than a line is split."""
    chars = max(12, int(width_in * TITLE_CHARS_PER_INCH))
    pieces = [p for p in re.split(r"(?<=[/_\- ])", text) if p]
    lines: list[str] = []
    line = ""
    for piece in pieces:
        while len(piece) > chars:  # one piece wider than a line
            if line:
                lines.append(line.rstrip())
                line = ""
            lines.append(piece[:chars])
            piece = piece[chars:]
        if len(line) + len(piece.rstrip()) > chars and line:
            lines.append(line.rstrip())
            line = ""
        line += piece
    if line.strip():
        lines.append(line.rstrip())
    return "\n".join(lines) or text


def ape_path_figure(results, title: str, plot_axes: str = "xy"):
    """`ape --plot`: one panel per estimate (its aligned path coloured by its APE, the reference
    dashed), titled with its label, wrapped to the panel's width; legends under the panels; two
    panels per row. Nothing overlaps or leaves the figure (tests/evaluation: text boxes)."""
    cols = min(2, len(results))
    rows = -(-len(results) // cols)
    panel_w, panel_h = 6.0, 5.4
    fig, axes = new_figure(panel_w * cols, panel_h * rows + 0.4, rows, cols)
    for k, ax in enumerate(axes.ravel()):
        if k >= len(results):
            ax.set_visible(False)
            continue
        r = results[k]
        draw_error_path(fig, ax, r.ref_xyz, r.est_xyz, r.errors, unit=r.unit,
                        est_label=f"estimate ({r.alignment.mode} aligned)", ref_label="reference",
                        title=wrapped(r.name, panel_w - 1.6), legend_below=True, axes=plot_axes)
    fig.suptitle(wrapped(title, panel_w * cols - 0.5))
    return fig


def _mark_events(ax, r: RunResult, kinds: tuple[str, ...]) -> list[str]:
    drawn = []
    for kind in kinds:
        times = [e.t_s for e in r.events if e.kind == kind]
        for t in times[:200]:
            ax.axvline(t, color=EVENT_COLOURS.get(kind, "0.5"), lw=0.6, alpha=0.6)
        if times:
            drawn.append(f"{EVENT_COLOURS.get(kind, 'grey').removeprefix('tab:')}: {kind.replace('_', ' ')}")
    return drawn


def slam_figures(r: RunResult, timing: dict[str, dict[str, float]] | None = None) -> list[tuple[str, str]]:
    """Path coloured by APE, APE over time and per-stage timing (`timing`: the stages to draw,
    default all in the result). Labels name online and smoothed only where they differ (lio)."""
    s = r.series
    lio = r.extra.get(S.METHOD, "lio") == "lio"
    out = []
    if S.EST_ALIGNED_XYZ in s and S.ape_err() in s and S.REF_XYZ in s:
        out += [_ape_path(s, lio), _ape_over_time(r, lio)]
    elif S.EST_XYZ in s and len(s[S.EST_XYZ]):
        out.append(_estimate_path(s, lio))
    timing = r.extra.get(S.TIMING_MS, {}) if timing is None else timing
    if timing:
        out.append(_stage_timing(timing))
    return out


def _ape_path(s: dict[str, np.ndarray], lio: bool) -> tuple[str, str]:
    fig, ax = new_figure(6.5, 5.0)
    overlays = []
    if S.EST_ONLINE_ALIGNED_XYZ in s and lio:
        overlays.append((s[S.EST_ONLINE_ALIGNED_XYZ], "online (as processed, SE(3) aligned)", "tab:red"))
    draw_error_path(fig, ax[0, 0], s[S.REF_XYZ], s[S.EST_ALIGNED_XYZ], s[S.ape_err()],
                    est_label="smoothed (SE(3) aligned)" if lio else "estimate (SE(3) aligned)",
                    overlays=overlays)
    return ("Trajectory in the plane (smoothed estimate coloured by its APE, online estimate red, ground "
            "truth dashed)" if lio else "Trajectory in the plane (estimate coloured by its APE, ground truth "
            "dashed)", svg(fig))


def _ape_over_time(r: RunResult, lio: bool) -> tuple[str, str]:
    s = r.series
    fig, axes = new_figure(7.0, 3.0)
    ax = axes[0, 0]
    t, e = decimate(s[S.ape_t()], s[S.ape_err()])
    ax.plot(t, e, lw=1.0, color="tab:blue",
            label="smoothed (re-anchored to the final keyframes)" if lio else "estimate")
    if S.ape_t(S.ONLINE) in s and S.ape_err(S.ONLINE) in s and lio:
        t, e = decimate(s[S.ape_t(S.ONLINE)], s[S.ape_err(S.ONLINE)])
        ax.plot(t, e, lw=1.0, color="tab:red", label="online (as processed)")
        ax.legend(fontsize="small", loc="upper left")
    marks = _mark_events(ax, r, ("loop_closure", "degeneracy"))
    ax.set(xlabel="time since log start (s)", ylabel="APE (m)", ylim=(0, None),
           title="APE over time" + (f" ({'; '.join(marks)})" if marks else ""))
    ax.grid(alpha=0.3)
    return ("APE (translation) over time" + (", online and smoothed" if lio else ""), svg(fig))


def _estimate_path(s: dict[str, np.ndarray], lio: bool) -> tuple[str, str]:
    fig, ax = new_figure(6.5, 5.0)
    xyz, = decimate(s[S.EST_XYZ])
    ax[0, 0].plot(xyz[:, 0], xyz[:, 1], lw=1.0)
    if S.KF_XYZ in s and len(s[S.KF_XYZ]) and lio:
        ax[0, 0].plot(s[S.KF_XYZ][:, 0], s[S.KF_XYZ][:, 1], "o", ms=3, color="tab:orange", label="keyframes")
        ax[0, 0].legend(fontsize="small")
    ax[0, 0].set_aspect("equal", adjustable="datalim")
    ax[0, 0].set(xlabel="x (m)", ylabel="y (m)", title="Estimated trajectory (no ground truth: APE not computed)")
    return ("Estimated trajectory in the plane", svg(fig))


def _stage_timing(timing: dict[str, dict[str, float]]) -> tuple[str, str]:
    fig, axes = new_figure(6.5, 0.6 + 0.35 * len(timing))
    ax = axes[0, 0]
    names = list(timing)[::-1]  # first stage on top
    ax.barh(names, [timing[n].get("mean", np.nan) for n in names], color="tab:blue", label="mean")
    ax.scatter([timing[n].get("p95", np.nan) for n in names], names, color="tab:red", zorder=3, label="p95")
    ax.set(xlabel="ms per processed sweep", title="Per-stage timing")
    ax.legend(fontsize="small", loc="lower right")
    ax.grid(axis="x", alpha=0.3)
    return ("Per-stage timing (bars: mean, dots: 95th percentile)", svg(fig))


def control_figures(r: RunResult) -> list[tuple[str, str]]:
    s = r.series
    out = []
    if r.extra.get(C.MODE) == "sweep" and C.SWEEP_GAIN_MISMATCH_MID in s:
        return [("Robustness sweep: fraction of runs with a funnel violation against the drive-gain mismatch",
                 _sweep_violations(s, r))]
    for ctrl in r.extra.get(C.CONTROLLERS, []):
        label = r.extra.get(C.LABELS, {}).get(ctrl, ctrl)
        t = s.get(C.time(ctrl), s.get(C.T))
        missing = [k for k in (C.side_series(ctrl, "left", C.V_REF),) if k not in s] + ([] if t is not None else
                                                                                        [C.time(ctrl)])
        if t is None or missing:  # said in the report, not skipped: a renamed series must not hide a figure
            out.append((f"{label}: no tracking figure: the result has no series {', '.join(missing)}", ""))
            continue
        funnel = C.FUNNEL_O in s and len(s[C.FUNNEL_O]) >= len(t) and ctrl in FUNNEL_CONTROLLERS
        caption = f"{label}: wheel-speed reference vs measured" + (", funnel band reference ± o(t)" if funnel else "")
        out.append((caption, _tracking(s, ctrl, label, t, funnel)))
        if C.side_series(ctrl, "left", C.U_RPM) in s:
            out.append((f"{label}: pump commands with the ±{U_MAX_RPM:.0f} RPM limits", _effort(s, r, ctrl, label, t)))
        if C.side_series(ctrl, "left", C.U_FB_RPM) in s:
            caption = f"{label}: feedback share |u_fb|/|U| per side" + (
                " and the adaptive parameter phi-hat(t)" if C.side_series(ctrl, "left", C.PHI_HAT) in s else "")
            out.append((caption, _feedback(s, ctrl, label, t)))
        if C.driven_xy(ctrl) in s and C.cte(ctrl) in s:
            out.append((f"{label}: driven path and cross-track error", _path(s, ctrl, label, t)))
    if C.BODE_W in s:
        out.append(("Open loop C(jw) K e^{-jwd}/(jw tau + 1) of the linear laws on the left drive (RAID: its "
                    "interior gain as a P law; dead band and clamp left out)", _bode(s)))
    return out


def _bode(s) -> str:
    fig, axes = new_figure(7.5, 4.6, rows=2, sharex=True)
    w = s[C.BODE_W]
    labels = {"raid": "RAID (interior gain)", "pid": "PID", "foptc": "FOPTC (frozen gain)",
              "foptc_restart": "FOPTC (at a restart)"}
    for law, label in labels.items():
        if C.bode_magnitude(law) in s:
            axes[0, 0].semilogx(w, s[C.bode_magnitude(law)], lw=1.0, label=label)
            axes[1, 0].semilogx(w, s[C.bode_phase(law)], lw=1.0, label=label)
    axes[0, 0].axhline(0.0, color="k", lw=0.6)
    axes[1, 0].axhline(-180.0, color="k", lw=0.6)
    axes[1, 0].set_ylim(-540.0, 45.0)
    axes[0, 0].set(ylabel="|L| (dB)", title="Open-loop Bode plot on the drive")
    axes[1, 0].set(xlabel="frequency (rad/s)", ylabel="phase (deg)")
    axes[0, 0].legend(fontsize="x-small", loc="lower left")
    for ax in axes[:, 0]:
        ax.grid(alpha=0.3, which="both")
    return svg(fig)


def _tracking(s, ctrl: str, label: str, t: np.ndarray, funnel: bool) -> str:
    fig, axes = new_figure(7.5, 5.0, rows=2, sharex=True)
    for ax, side in zip(axes[:, 0], ("left", "right"), strict=True):
        arrays = [t, s[C.side_series(ctrl, side, C.V_REF)], s[C.side_series(ctrl, side, C.V_MEAS)]]
        if funnel:
            arrays.append(s[C.FUNNEL_O])
        tt, rr, mm, *o = decimate(*arrays)
        if o:
            ax.fill_between(tt, rr - o[0], rr + o[0], color="tab:orange", alpha=0.25, lw=0, label="funnel ±o(t)")
        ax.plot(tt, rr, lw=1.0, color="k", label="reference")
        ax.plot(tt, mm, lw=0.8, color="tab:blue", label="measured")
        ax.set_ylabel(f"{side} wheel (m/s)")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="upper right", fontsize="x-small", ncols=3)
    axes[-1, 0].set_xlabel("time (s)")
    axes[0, 0].set_title(f"{label}: wheel-speed tracking")
    return svg(fig)


def _effort(s, r: RunResult, ctrl: str, label: str, t: np.ndarray) -> str:
    fig, ax = new_figure(7.5, 2.8)
    ax = ax[0, 0]
    for side, colour in (("left", "tab:blue"), ("right", "tab:orange")):
        tt, uu = decimate(t, s[C.side_series(ctrl, side, C.U_RPM)])
        ax.plot(tt, uu, lw=0.8, color=colour, label=side)
    for lim in (U_MAX_RPM, -U_MAX_RPM):
        ax.axhline(lim, color="tab:red", ls="--", lw=0.8)
    ax.text(1.0, U_MAX_RPM, f" {U_MAX_RPM:.0f}", color="tab:red", fontsize="x-small", va="center",
            transform=ax.get_yaxis_transform())
    ax.text(1.0, -U_MAX_RPM, f" {-U_MAX_RPM:.0f}", color="tab:red", fontsize="x-small", va="center",
            transform=ax.get_yaxis_transform())
    ax.set_ylim(-1.15 * U_MAX_RPM, 1.15 * U_MAX_RPM)
    stops = [e.t_s for e in r.events if e.kind == "safety_stop"]
    for ts in stops[:200]:
        ax.axvline(ts, color="k", lw=0.6, ls=":")
    ax.set(xlabel="time (s)", ylabel="pump command (RPM)",
           title=f"{label}: control effort" + (" (dotted: safety stops)" if stops else ""))
    ax.legend(fontsize="small", loc="lower right", ncols=2)
    ax.grid(alpha=0.3)
    return svg(fig)


def _feedback(s, ctrl: str, label: str, t: np.ndarray) -> str:
    """What the feedback does: |u_fb|/|U| (0 = feed-forward alone) and, for RAID, phi-hat(t)."""
    phi = C.side_series(ctrl, "left", C.PHI_HAT) in s
    fig, axes = new_figure(7.5, 4.6 if phi else 2.6, rows=2 if phi else 1, sharex=True)
    ax = axes[0, 0]
    for side, colour in (("left", "tab:blue"), ("right", "tab:orange")):
        u, fb = np.abs(s[C.side_series(ctrl, side, C.U_RPM)]), np.abs(s[C.side_series(ctrl, side, C.U_FB_RPM)])
        share = np.where(u > 1.0, fb / np.maximum(u, 1.0), np.nan)
        tt, sh = decimate(t, share)
        ax.plot(tt, sh, lw=0.7, color=colour, label=side)
    ax.set(ylabel="|u_fb| / |U|", ylim=(0.0, 1.05), title=f"{label}: share of the command that is feedback")
    ax.legend(fontsize="small", loc="upper right", ncols=2)
    ax.grid(alpha=0.3)
    if phi:
        ax = axes[1, 0]
        for side, colour in (("left", "tab:blue"), ("right", "tab:orange")):
            tt, ph = decimate(t, s[C.side_series(ctrl, side, C.PHI_HAT)])
            ax.plot(tt, ph, lw=0.8, color=colour, label=side)
        ax.set(ylabel="phi-hat", title="RAID adaptive parameter phi-hat(t)")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time (s)")
    return svg(fig)


def _sweep_violations(s, r: RunResult) -> str:
    fig, ax = new_figure(7.0, 3.2)
    ax = ax[0, 0]
    mid = 100.0 * s[C.SWEEP_GAIN_MISMATCH_MID]
    styles = itertools.cycle([("-", "o"), ("--", "s"), (":", "^"), ("-.", "D"), ((0, (5, 1, 1, 1)), "v")])
    for ctrl in r.extra.get(C.CONTROLLERS, []):
        if C.sweep_violation_rate(ctrl) in s:  # styles differ: equal rates would hide a line
            ls, marker = next(styles)
            ax.plot(mid, s[C.sweep_violation_rate(ctrl)], ls=ls, marker=marker, lw=1.0, ms=4,
                    label=r.extra.get(C.LABELS, {}).get(ctrl, ctrl))
    ax.set(xlabel="drive gain mismatch (%, plant vs the controllers' model)",
           ylabel="runs with a funnel violation", ylim=(-0.03, 1.03),
           title=f"Robustness sweep ({r.extra.get(C.RUNS, '?')} plants per controller)")
    ax.legend(fontsize="x-small", loc="best")
    ax.grid(alpha=0.3)
    return svg(fig)


def _path(s, ctrl: str, label: str, t: np.ndarray) -> str:
    fig, axes = new_figure(7.5, 3.4, cols=2)
    xy, cte = s[C.driven_xy(ctrl)], s[C.cte(ctrl)]
    xy, = decimate(xy)
    ax = axes[0, 0]
    if C.PATH_XY in s and len(s[C.PATH_XY]):
        ax.plot(s[C.PATH_XY][:, 0], s[C.PATH_XY][:, 1], "k--", lw=0.8, marker="o", ms=3, label="planned")
    ax.plot(xy[:, 0], xy[:, 1], lw=1.0, color="tab:blue", label="driven")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel="x (m)", ylabel="y (m)", title="Path")
    ax.legend(fontsize="x-small")
    ax = axes[0, 1]
    if len(t) >= len(cte):
        tt, cc = decimate(t[: len(cte)], cte)
        ax.plot(tt, cc, lw=0.8)
        ax.set_xlabel("time (s)")
    else:  # no time base of the same length: index along the run
        cc, = decimate(cte)
        ax.plot(np.linspace(0, 100, len(cc)), cc, lw=0.8)
        ax.set_xlabel("progress along the run (%)")
    ax.axhline(0, color="0.5", lw=0.6)
    ax.set(ylabel="cross-track error (m)", title="Cross-track error")
    ax.grid(alpha=0.3)
    return svg(fig)
