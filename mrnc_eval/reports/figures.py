"""Report figures with matplotlib's object API (no pyplot state), returned as inline SVG."""

from __future__ import annotations

import io
import itertools
import re

import numpy as np

from mrnc_eval.results import RunResult

U_MAX_RPM = 1250.0
MAX_POINTS = 4000  # per line: plots are decimated, statistics never are


_FIGURE_IDS = itertools.count(1)
_ID = re.compile(r'id="([^"]+)"')
_REF = re.compile(r'(href="#|url\(#)([^")]+)')


def _svg(fig) -> str:
    """Inline SVG with text as text and ids made unique per figure: several matplotlib SVGs in one
    page would otherwise share ids such as "patch_1" and pick up each other's clip paths."""
    import matplotlib
    from matplotlib.backends.backend_svg import FigureCanvasSVG

    buf = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        FigureCanvasSVG(fig).print_svg(buf)
    text = buf.getvalue()
    text = text[text.index("<svg"):]  # drop the XML prolog: the SVG is inlined in HTML
    prefix = f"f{next(_FIGURE_IDS)}-"
    text = _ID.sub(lambda m: f'id="{prefix}{m.group(1)}"', text)
    return _REF.sub(lambda m: f"{m.group(1)}{prefix}{m.group(2)}", text)


def _fig(w=7.0, h=3.2, rows=1, cols=1):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False)
    return fig, axes


def _dec(*arrays):
    n = len(arrays[0])
    step = max(1, n // MAX_POINTS)
    return [a[::step] for a in arrays]


def slam_figures(r: RunResult) -> list[tuple[str, str]]:
    s = r.series
    out = []
    if "est_aligned_xyz" in s and "ape_err_m" in s:
        fig, ax = _fig(6.5, 5.0)
        ax = ax[0, 0]
        ref, est, err = _dec(s["ref_xyz"], s["est_aligned_xyz"], s["ape_err_m"])
        ax.plot(ref[:, 0], ref[:, 1], color="0.6", lw=1.0, ls="--", label="reference")
        sc = ax.scatter(est[:, 0], est[:, 1], c=err, s=6, cmap="viridis", label="estimate (SE(3) aligned)")
        fig.colorbar(sc, ax=ax, label="APE (m)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(loc="best", fontsize="small")
        ax.set_title("Trajectory in the plane, coloured by APE")
        out.append(("Trajectory coloured by APE", _svg(fig)))
        fig, ax = _fig()
        t, e = _dec(s["ape_t"], s["ape_err_m"])
        ax[0, 0].plot(t, e, lw=1.0)
        for ev in r.events:
            if ev.kind == "loop_closure":
                ax[0, 0].axvline(ev.t_s, color="tab:green", lw=0.6, alpha=0.6)
        ax[0, 0].set_xlabel("time (s)")
        ax[0, 0].set_ylabel("APE (m)")
        ax[0, 0].set_title("APE over time (green: loop closures)")
        out.append(("APE over time", _svg(fig)))
    elif "est_xyz" in s:
        fig, ax = _fig(6.5, 5.0)
        xyz, = _dec(s["est_xyz"])
        ax[0, 0].plot(xyz[:, 0], xyz[:, 1], lw=1.0)
        ax[0, 0].set_aspect("equal", adjustable="datalim")
        ax[0, 0].set_title("Estimated trajectory (no ground truth)")
        out.append(("Trajectory", _svg(fig)))
    timing = r.extra.get("timing_ms", {})
    if timing:
        fig, ax = _fig(6.0, 2.8)
        names = list(timing)
        ax[0, 0].barh(names, [timing[n]["mean"] for n in names], color="tab:blue", label="mean")
        ax[0, 0].scatter([timing[n]["p95"] for n in names], names, color="tab:red", zorder=3, label="p95")
        ax[0, 0].set_xlabel("ms per processed sweep")
        ax[0, 0].legend(fontsize="small")
        ax[0, 0].set_title("Per-stage timing")
        out.append(("Per-stage timing", _svg(fig)))
    return out


def control_figures(r: RunResult) -> list[tuple[str, str]]:
    s = r.series
    out = []
    for ctrl in r.extra.get("controllers", []):
        label = r.extra.get("labels", {}).get(ctrl, ctrl)
        t = s.get(f"{ctrl}_t", s.get("t"))
        if t is None or f"{ctrl}_left_v_ref" not in s:
            continue
        fig, axes = _fig(7.5, 5.2, rows=2)
        for ax, side in zip(axes[:, 0], ("left", "right")):
            ref, meas = s[f"{ctrl}_{side}_v_ref"], s[f"{ctrl}_{side}_v_meas"]
            n = min(t.size, ref.size)
            tt, rr, mm = _dec(t[:n], ref[:n], meas[:n])
            ax.plot(tt, mm, lw=0.8, label="measured")
            ax.plot(tt, rr, lw=1.0, color="k", label="reference")
            if "funnel_o" in s and s["funnel_o"].size >= n:
                o, = _dec(s["funnel_o"][:n])
                ax.fill_between(tt, rr - o, rr + o, color="tab:orange", alpha=0.2, label="funnel o(t)")
            ax.set_ylabel(f"{side} (m/s)")
            ax.legend(loc="lower right", fontsize="x-small", ncols=3)
        axes[-1, 0].set_xlabel("time (s)")
        axes[0, 0].set_title(f"{label}: wheel speed tracking")
        out.append((f"{label}: reference vs measured", _svg(fig)))
        fig, ax = _fig(7.5, 2.8)
        for side in ("left", "right"):
            u = s[f"{ctrl}_{side}_u_rpm"]
            n = min(t.size, u.size)
            tt, uu = _dec(t[:n], u[:n])
            ax[0, 0].plot(tt, uu, lw=0.8, label=side)
        for lim in (U_MAX_RPM, -U_MAX_RPM):
            ax[0, 0].axhline(lim, color="tab:red", ls="--", lw=0.8)
        ax[0, 0].set_ylabel("pump command (RPM)")
        ax[0, 0].set_xlabel("time (s)")
        ax[0, 0].legend(fontsize="small")
        ax[0, 0].set_title(f"{label}: control effort (limits +/-1250 RPM)")
        out.append((f"{label}: control effort", _svg(fig)))
        if f"{ctrl}_xy" in s and "path_xy" in s:
            fig, axes = _fig(7.5, 3.2, cols=2)
            xy, cte = _dec(s[f"{ctrl}_xy"], s[f"{ctrl}_cte_m"])
            axes[0, 0].plot(s["path_xy"][:, 0], s["path_xy"][:, 1], "k--", lw=0.8, marker="o", ms=3, label="waypoints")
            axes[0, 0].plot(xy[:, 0], xy[:, 1], lw=1.0, label="driven")
            axes[0, 0].set_aspect("equal", adjustable="datalim")
            axes[0, 0].legend(fontsize="x-small")
            axes[0, 0].set_title("Path")
            axes[0, 1].plot(np.arange(cte.size) / max(cte.size - 1, 1) * 100, cte, lw=0.8)
            axes[0, 1].set_xlabel("progress along the run (%)")
            axes[0, 1].set_ylabel("cross-track error (m)")
            axes[0, 1].set_title("Cross-track error")
            out.append((f"{label}: path and cross-track error", _svg(fig)))
    return out
