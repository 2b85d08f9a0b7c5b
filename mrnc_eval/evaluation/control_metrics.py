"""Control metrics of Table II and beyond (paper-notes 6, control-reference 2). Pure numpy.

Step metrics are segment-based: the run is split where the reference changes by more than
a threshold; per segment with step delta = r - y0:
  settling time = first time after which |y - r| stays within max(band |delta|, floor);
  overshoot %   = 100 max(0, max sign(delta) (y - r)) / |delta|;
  steady-state error = mean |r - y| (or |mean(r - y)|, configurable) over the last window
                       of the segment, with the signed mean kept beside it;
  rise time     = 10 % to 90 % of the normalised response.
These work for down-steps and non-zero initial values (python-control's step_info assumes
y(0) = 0 and mishandles both).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.control.config import MetricsConfig, PaperMetricsConfig
from mrnc_eval.evaluation.step_readings import funnel_reading, stepinfo

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class StepMetrics:
    t_start: float
    delta: float
    settling_time_s: float  # NaN when not settled by the end of the segment
    overshoot_pct: float
    steady_state_error: float  # signed mean of r - y over the window
    rise_time_s: float
    steady_state_abs_error: float = float("nan")  # mean |r - y| over the window


def step_response(t: FloatArray, y: FloatArray, r: FloatArray | float, y0: float, cfg: MetricsConfig,
                  target: float | None = None) -> StepMetrics:
    """Metrics of one segment: response y to reference r (array or constant) from y0; the step
    size is target - y0 (target defaults to the final reference value)."""
    r = np.broadcast_to(np.asarray(r, dtype=float), y.shape)
    delta = (r[-1] if target is None else target) - y0
    err = y - r
    band = max(cfg.settling_band * abs(delta), cfg.settling_floor_mps)
    outside = np.flatnonzero(np.abs(err) > band)
    if outside.size == 0:
        ts = 0.0
    elif outside[-1] == err.size - 1:
        ts = float("nan")
    else:
        ts = float(t[outside[-1] + 1] - t[0])
    sgn = np.sign(delta) if delta != 0 else 1.0
    overshoot = 100.0 * max(0.0, float(np.max(sgn * err))) / abs(delta) if delta != 0 else 0.0
    duration = t[-1] - t[0]
    window = min(cfg.steady_window_fraction * duration, cfg.steady_window_max_s)
    tail = t >= t[-1] - window
    sse = float(np.mean(r[tail] - y[tail]))
    sse_abs = float(np.mean(np.abs(r[tail] - y[tail])))
    rise = float("nan")
    if delta != 0:
        yn = (y - y0) / delta
        i10 = np.flatnonzero(yn >= 0.1)
        i90 = np.flatnonzero(yn >= 0.9)
        if i10.size and i90.size:
            rise = float(t[i90[0]] - t[i10[0]])
    return StepMetrics(float(t[0]), float(delta), ts, overshoot, sse, rise, sse_abs)


def step_segments(t: FloatArray, r: FloatArray, cfg: MetricsConfig) -> list[tuple[int, int, int]]:
    """(start, ramp_end, end) of each step: a jump or ramp of the reference changing it by at least
    min_step, up to the start of the next one. Slew-limited references are ramps, not jumps."""
    rate = np.abs(np.diff(r)) / np.maximum(np.diff(t), 1e-12)
    moving = np.concatenate([rate > cfg.ramp_rate_mps2, [False]])
    edges = np.diff(np.concatenate([[0], moving.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # ramp [s, e]
    ends = np.minimum(ends, r.size - 1)
    ramps = [(int(a), int(b)) for a, b in zip(starts, ends, strict=True) if abs(r[b] - r[a]) >= cfg.min_step_mps]
    out = []
    for k, (a, b) in enumerate(ramps):
        end = ramps[k + 1][0] if k + 1 < len(ramps) else r.size
        end = min(end, int(np.searchsorted(t, t[b] + cfg.step_window_s)))
        if end - a > 10:
            out.append((a, b, end))
    return out


def tracking_metrics(t: FloatArray, r: FloatArray, y: FloatArray, u: FloatArray, o: FloatArray, *, u_max: float,
                     slip: FloatArray | None, cfg: MetricsConfig, o_floor: float = 0.11) -> dict[str, float]:
    """Per-side metrics with unit-bearing keys. Reference changes smaller than cfg.min_step_mps
    (continuous pure-pursuit corrections) are not steps. Settling and overshoot in three readings:
    reference-centred (settling_time_s, overshoot_pct), stepinfo (final value) and funnel (floor
    o_floor m/s), see evaluation/step_readings.py."""
    dt = np.diff(t, append=t[-1] + (t[-1] - t[-2] if t.size > 1 else 0.0))
    e = y - r
    ae = np.abs(e)
    steps, infos, funnel_reads = [], [], []
    for a, ramp_end, end in step_segments(t, r, cfg):
        steps.append(step_response(t[a:end], y[a:end], r[a:end], float(y[a]), cfg, target=float(r[ramp_end])))
        window = min(cfg.steady_window_fraction * (t[end - 1] - t[a]), cfg.steady_window_max_s)
        infos.append(stepinfo(t[a:end], y[a:end], float(y[a]), float(r[end - 1]), band=cfg.settling_band,
                              floor=cfg.settling_floor_mps, final_window_s=window,
                              r_step=float(r[ramp_end] - y[a])))
        funnel_reads.append(funnel_reading(t[a:end], y[a:end], r[a:end], o[a:end], o_floor))
    sat = np.abs(u) >= u_max - cfg.saturation_tolerance_rpm
    out = {
        "settling_time_s": _worst([s.settling_time_s for s in steps]),
        "overshoot_pct": float(max((s.overshoot_pct for s in steps), default=float("nan"))),
        "rise_time_s": _median_ignoring_nan([s.rise_time_s for s in steps]),
        # over the end window of each step segment, worst segment
        "steady_state_error_mps": float(max((s.steady_state_abs_error if cfg.steady_state_statistic == "mean_abs"
                                             else abs(s.steady_state_error) for s in steps), default=float("nan"))),
        "steady_state_bias_mps": float(max((s.steady_state_error for s in steps), key=abs, default=float("nan"))),
        "n_steps": len(steps),
        # final-value (stepinfo) reading, steady offset apart; funnel reading (evaluation/step_readings.py)
        "stepinfo_settling_time_s": _nanmax([i.settling_time_s for i in infos]),
        "stepinfo_overshoot_pct": _nanmax([i.overshoot_pct for i in infos]),
        "steady_offset_mps": float(max((i.steady_offset for i in infos), key=abs, default=float("nan"))),
        "funnel_settling_time_s": float(max((f[0] for f in funnel_reads), default=float("nan"))),
        "funnel_peak_use_pct": float(max((f[1] for f in funnel_reads), default=float("nan"))),
        "iae": float(np.sum(ae * dt)),
        "ise": float(np.sum(e * e * dt)),
        "itae": float(np.sum((t - t[0]) * ae * dt)),
        "rms_error_mps": float(np.sqrt(np.mean(e * e))),
        "max_abs_error_mps": float(ae.max()),
        "funnel_violations": int(np.count_nonzero(ae >= o)),
        "max_e_over_o": float(np.max(ae / o)),
        "saturation_ratio": float(np.mean(sat)),
        "longest_saturation_s": _longest_run(sat, dt),
        "max_abs_command_rpm": float(np.max(np.abs(u))),
        "control_effort": float(np.sum(u * u * dt)),
        "total_variation_rpm": float(np.sum(np.abs(np.diff(u)))),
    }
    out["recovery_time_s"] = (recovery_time(t, ae, slip, cfg.recovery_band_mps, cfg.recovery_hold_s,
                                            cfg.recovery_horizon_s)
                              if slip is not None else float("nan"))
    return out


def feedback_share(u: FloatArray, u_fb: FloatArray, min_rpm: float) -> tuple[float, float]:
    """(mean, 95th percentile) of |u_fb| / |U| over samples with |U| > min_rpm: how much of the
    applied command is feedback rather than feed-forward (0 for the feed-forward alone)."""
    active = np.abs(u) > min_rpm
    if not active.any():
        return float("nan"), float("nan")
    share = np.abs(u_fb[active]) / np.abs(u[active])
    return float(np.mean(share)), float(np.percentile(share, 95))


def moving_mean(y: FloatArray, n: int) -> FloatArray:
    """Centred moving mean over n samples (edges: mean of the samples available)."""
    if n <= 1:
        return np.asarray(y, dtype=float)
    kernel = np.ones(n)
    return np.convolve(y, kernel, mode="same") / np.convolve(np.ones_like(y, dtype=float), kernel, mode="same")


def paper_metrics(t: FloatArray, r: FloatArray, y: FloatArray, cfg: PaperMetricsConfig) -> dict[str, float]:
    """Table II read the way the paper's numbers read, for one side (keys prefixed `paper_`):
    - cruise speed r_c: median reference over the second half of the start-up window;
    - start-up step 0 -> r_c: the window [t0, t0 + startup_window_s], t0 = first non-zero reference;
      settling time = first time after t0 from which |y - r_c| <= band r_c to the window's end
      (inf: not settled), overshoot % = 100 max(0, max y - r_c) / r_c over the window;
    - steady-state error = mean |r - y| after the window wherever the reference is within
      cruise_tolerance of r_c (steady cruise; slip patches included, as in a field run).
    y is smoothed by a centred moving mean over smoothing_s first (white measurement noise)."""
    nan = float("nan")
    out = {"paper_cruise_speed_mps": nan, "paper_settling_time_s": nan, "paper_overshoot_pct": nan,
           "paper_steady_state_error_mps": nan, "paper_stepinfo_settling_time_s": nan,
           "paper_stepinfo_overshoot_pct": nan, "paper_steady_offset_mps": nan}
    moving = np.flatnonzero(np.abs(r) > 1e-6)
    if moving.size == 0 or t.size < 3:
        return out
    dt = float(np.median(np.diff(t)))
    ys = moving_mean(y, int(round(cfg.smoothing_s / dt)))
    t0 = t[moving[0]]
    window = (t >= t0) & (t <= t0 + cfg.startup_window_s)
    late = window & (t >= t0 + 0.5 * cfg.startup_window_s)
    if not late.any():
        return out
    rc = float(np.median(r[late]))
    if rc <= 0.0:
        return out
    out["paper_cruise_speed_mps"] = rc
    tw, yw = t[window], ys[window]
    outside = np.flatnonzero(np.abs(yw - rc) > cfg.band * rc)
    if outside.size == 0:
        out["paper_settling_time_s"] = 0.0
    elif outside[-1] == yw.size - 1:
        out["paper_settling_time_s"] = float("inf")
    else:
        out["paper_settling_time_s"] = float(tw[outside[-1] + 1] - t0)
    out["paper_overshoot_pct"] = 100.0 * max(0.0, float(np.max(yw)) - rc) / rc
    # final-value reading of the same start-up step (y0 = 0; y_f over the window's second half)
    info = stepinfo(tw, yw, 0.0, rc, band=cfg.band, floor=0.0, final_window_s=0.5 * cfg.startup_window_s)
    out["paper_stepinfo_settling_time_s"] = info.settling_time_s
    out["paper_stepinfo_overshoot_pct"] = info.overshoot_pct
    out["paper_steady_offset_mps"] = info.steady_offset
    cruise = (t > t0 + cfg.startup_window_s) & (np.abs(r - rc) <= cfg.cruise_tolerance * rc)
    if cruise.any():
        out["paper_steady_state_error_mps"] = float(np.mean(np.abs(r[cruise] - ys[cruise])))
    return out


def _nanmax(values: list[float]) -> float:
    """Largest value ignoring NaN (a segment without a reading); NaN when none has one."""
    kept = [v for v in values if not np.isnan(v)]
    return float(max(kept)) if kept else float("nan")


def _worst(values: list[float]) -> float:
    """Largest value; an unsettled step (NaN) makes the aggregate inf."""
    if not values:
        return float("nan")
    return float("inf") if any(np.isnan(values)) else float(max(values))


def _longest_run(mask: NDArray[np.bool_], dt: FloatArray) -> float:
    if not mask.any():
        return 0.0
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    csum = np.concatenate([[0.0], np.cumsum(dt)])
    return float(np.max(csum[ends] - csum[starts]))


def recovery_time(t: FloatArray, abs_err: FloatArray, slip: FloatArray, band: float, hold_s: float = 1.0,
                  horizon_s: float = 15.0) -> float:
    """Worst time (s) from a slip event (a patch entered or left) until |e| is back below band
    and stays there for hold_s; NaN if there was no event, inf if not recovered within horizon_s."""
    events = recovery_events(t, abs_err, slip, band, hold_s, horizon_s)
    return max((r for _t, _kind, r in events), default=float("nan"))


def recovery_events(t: FloatArray, abs_err: FloatArray, slip: FloatArray, band: float, hold_s: float = 1.0,
                    horizon_s: float = 15.0) -> list[tuple[float, str, float]]:
    """Per slip event (time s, "slip on" or "slip off", recovery s): the time from the event until
    |e| is back below band and stays there for hold_s (inf if not within horizon_s)."""
    changes = np.flatnonzero(np.diff(slip) != 0) + 1
    out = []
    inside = abs_err <= band
    for c in changes:
        stop = np.searchsorted(t, t[c] + horizon_s + hold_s)
        ok = inside[c:stop]
        rec = float("inf")
        run_start = None
        for k in np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(np.int8), [0]])) != 0):
            if run_start is None:
                run_start = k
                continue
            if t[c + k - 1] - t[c + run_start] >= hold_s:
                rec = float(t[c + run_start] - t[c])
                break
            run_start = None
        out.append((float(t[c]), "slip on" if slip[c] > slip[c - 1] else "slip off", rec))
    return out


def estimate_slip(t: FloatArray, v_wheel: FloatArray, v_ground: FloatArray, *, window_s: float = 1.0,
                  threshold: float = 0.05, min_speed_mps: float = 0.05, min_duration_s: float = 1.0) -> FloatArray:
    """Slip patches of one side from a recording: s = 1 - v_ground / v_wheel, averaged over
    window_s, is a patch where it exceeds threshold for at least min_duration_s. Returns the
    mean slip inside each patch and 0 elsewhere (a piecewise-constant series, as simulated)."""
    moving = np.abs(v_wheel) > min_speed_mps
    raw = np.where(moving, 1.0 - v_ground / np.where(moving, v_wheel, 1.0), 0.0)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    n = max(1, int(round(window_s / dt)))
    smooth = np.convolve(raw, np.ones(n) / n, mode="same")
    inside = (smooth > threshold) & moving
    out = np.zeros_like(t, dtype=float)
    edges = np.diff(np.concatenate([[0], inside.astype(np.int8), [0]]))
    for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
        if t[b - 1] - t[a] >= min_duration_s:
            out[a:b] = float(np.mean(raw[a:b]))
    return out


def cross_track(x: FloatArray, y: FloatArray, waypoints: FloatArray,
                chunk: int = 4096) -> tuple[FloatArray, FloatArray]:
    """Signed distance (m, + = left of the path) to the nearest path segment and that segment's
    heading (rad), per sample; computed in chunks so long logs with dense paths stay bounded."""
    a, b = waypoints[:-1], waypoints[1:]
    d = b - a
    L2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-12)
    p_all = np.c_[x, y]
    cte = np.empty(p_all.shape[0])
    seg = np.empty(p_all.shape[0], dtype=np.intp)
    for lo in range(0, p_all.shape[0], chunk):
        p = p_all[lo:lo + chunk]
        s = np.clip(np.einsum("nkj,kj->nk", p[:, None, :] - a[None], d) / L2, 0.0, 1.0)
        proj = a[None] + s[..., None] * d[None]
        dist = np.linalg.norm(p[:, None, :] - proj, axis=2)
        k = np.argmin(dist, axis=1)
        rows = np.arange(k.size)
        rel = p - proj[rows, k]
        cross = d[k, 0] * rel[:, 1] - d[k, 1] * rel[:, 0]
        cte[lo:lo + chunk] = np.where(cross < 0, -1.0, 1.0) * dist[rows, k]
        seg[lo:lo + chunk] = k
    return cte, np.arctan2(d[seg, 1], d[seg, 0])


def path_metrics(x: FloatArray, y: FloatArray, yaw: FloatArray, waypoints: FloatArray,
                 completion_time_s: float) -> dict[str, Any]:
    """Cross-track error against the path segments, heading error against the nearest segment's
    direction, completion time (NaN when the goal was not reached) and final distance to the goal.
    The signed cross-track series is returned under "_cte" (m)."""
    cte, path_yaw = cross_track(x, y, waypoints)
    herr = (yaw - path_yaw + np.pi) % (2 * np.pi) - np.pi
    return {
        "cross_track_rms_m": float(np.sqrt(np.mean(cte ** 2))),
        "cross_track_mean_abs_m": float(np.mean(np.abs(cte))),
        "cross_track_max_m": float(np.max(np.abs(cte))),
        "cross_track_p95_m": float(np.percentile(np.abs(cte), 95)),
        "heading_error_rms_rad": float(np.sqrt(np.mean(herr ** 2))),
        "completion_time_s": float(completion_time_s),
        "final_position_error_m": float(np.hypot(x[-1] - waypoints[-1, 0], y[-1] - waypoints[-1, 1])),
        "_cte": cte,
    }


def _median_ignoring_nan(values: list[float]) -> float:
    """Median ignoring NaN (a step that never reached its rise level); NaN when all are,
    without numpy's all-NaN warning."""
    kept = np.asarray(values, float)
    kept = kept[~np.isnan(kept)]
    return float(np.median(kept)) if kept.size else float("nan")
