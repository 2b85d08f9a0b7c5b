"""A standstill before the drive: the machine stands with its engine running (IMU vibration,
white noise and biases, no motion) for a few seconds before it sets off, as most field logs
start. The IMU's noise and biases can be measured back from such a stretch (slam/imu_noise.py)."""

from __future__ import annotations

from dataclasses import fields, replace
from typing import Any

import numpy as np

# trace columns that hold their first value while standing (pose), the rest are rates/commands -> 0
_HELD = ("x", "y", "yaw")


def hold_start(trace: Any, seconds: float) -> Any:
    """The control trace (control.closed_loop.ClosedLoopTrace) delayed by `seconds` (s), with the
    start pose held and every speed, command and slip zero before it, and its events (t_s) delayed
    alike. 0 returns the trace as is."""
    if seconds <= 0:
        return trace
    t = np.asarray(trace.t, float)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.01
    pre = np.arange(0.0, seconds, dt)
    n_pre, n = pre.size, t.size
    changes: dict[str, Any] = {"t": np.r_[pre + t[0], t + seconds]}
    for f in fields(trace):
        a = getattr(trace, f.name)
        if f.name == "t" or not isinstance(a, np.ndarray) or a.ndim != 1 or a.size != n:
            continue
        head = np.full(n_pre, a[0]) if f.name in _HELD else np.zeros(n_pre)
        changes[f.name] = np.r_[head, a]
    changes["completion_time_s"] = float(trace.completion_time_s) + seconds
    changes["events"] = [{**e, "t_s": float(e["t_s"]) + seconds} if "t_s" in e else e for e in trace.events]
    return replace(trace, **changes)
