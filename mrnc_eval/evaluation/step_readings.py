"""Three declared readings of one step response (issue 25 item 7), each with its own semantics:

- stepinfo (final value, as MATLAB stepinfo and python-control step_info): y_f = the settled value
  (mean over the end window: the measurement is noisy, MATLAB's last sample is not robust), step
  size y_f - y0; settling = first time after which |y - y_f| <= band |y_f - y0| (last exit + 1
  sample); overshoot % = 100 max(0, max sign (y - y_f)) / |y_f - y0|. A steady offset from the
  reference is NOT overshoot here: it is reported apart as steady offset y_f - r.
- reference (reference-centred, control_metrics.step_response): band and overshoot about the
  reference r; a steady offset above r counts as overshoot.
- funnel: settling = first time after which |y - r| <= o_b (the funnel floor) for good; "overshoot"
  = 100 max |e| / o(t), the peak use of the funnel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class StepInfo:
    settling_time_s: float  # from t[0]; inf when still outside the band at the end
    overshoot_pct: float  # beyond the final value, % of the step to it
    final_value: float  # y_f, m/s
    steady_offset: float  # y_f - r_end, m/s (signed)


def last_exit_time(t: FloatArray, outside: NDArray[np.bool_]) -> float:
    """First time (from t[0]) after which `outside` is False for good: 0 if never outside, inf if
    outside at the last sample."""
    idx = np.flatnonzero(outside)
    if idx.size == 0:
        return 0.0
    if idx[-1] == outside.size - 1:
        return float("inf")
    return float(t[idx[-1] + 1] - t[0])


def stepinfo(t: FloatArray, y: FloatArray, y0: float, r_end: float, *, band: float, floor: float,
             final_window_s: float, r_step: float | None = None) -> StepInfo:
    """Final-value reading of the response y (from y0) over one segment; y_f = mean of y over the
    last final_window_s; band relative to |y_f - y0| with an absolute floor (m/s). With the reference's
    step r_step (m/s) given, a response that did not travel half of it is no step response to read
    (NaN settling and overshoot: dividing by a near-zero y_f - y0 gives meaningless percentages)."""
    tail = t >= t[-1] - final_window_s
    y_f = float(np.mean(y[tail]))
    delta = y_f - y0
    if r_step is not None and abs(delta) < 0.5 * abs(r_step):
        return StepInfo(settling_time_s=float("nan"), overshoot_pct=float("nan"), final_value=y_f,
                        steady_offset=y_f - r_end)
    width = max(band * abs(delta), floor)
    ts = last_exit_time(t, np.abs(y - y_f) > width)
    sgn = 1.0 if delta >= 0 else -1.0
    os = 100.0 * max(0.0, float(np.max(sgn * (y - y_f)))) / abs(delta) if delta != 0 else 0.0
    return StepInfo(settling_time_s=ts, overshoot_pct=os, final_value=y_f, steady_offset=y_f - r_end)


def funnel_reading(t: FloatArray, y: FloatArray, r: FloatArray, o: FloatArray, o_b: float) -> tuple[float, float]:
    """(settling into the funnel floor s, peak funnel use % = 100 max |e| / o)."""
    e = np.abs(y - r)
    return last_exit_time(t, e > o_b), float(100.0 * np.max(e / o))
