"""Issue 25 item 7: the stepinfo (final value) reading against closed forms, and overshoot kept apart
from a steady offset (the reference-centred reading counts an offset above the reference as overshoot)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mrnc_eval.config import Config
from mrnc_eval.evaluation.control_metrics import step_response
from mrnc_eval.evaluation.step_readings import funnel_reading, stepinfo

TAU = 0.5


def _first_order(final: float, t_end: float = 12.0, dt: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(0.0, t_end, dt)
    return t, final * (1.0 - np.exp(-t / TAU))


def test_stepinfo_settling_matches_tau_ln50() -> None:
    t, y = _first_order(1.0)
    info = stepinfo(t, y, 0.0, 1.0, band=0.02, floor=0.0, final_window_s=1.0)
    assert info.settling_time_s == pytest.approx(TAU * math.log(50.0), abs=2e-3)  # 1.956 s (python-control)
    assert info.overshoot_pct == pytest.approx(0.0, abs=1e-6)
    assert abs(info.steady_offset) < 1e-6


def test_a_steady_offset_is_not_overshoot_in_the_stepinfo_reading() -> None:
    """Response settles 5 % above the reference: stepinfo says 0 % overshoot and +0.05 offset; the
    reference-centred reading (the negative control of this test) calls the offset 5 % overshoot."""
    t, y = _first_order(1.05)
    info = stepinfo(t, y, 0.0, 1.0, band=0.02, floor=0.0, final_window_s=1.0)
    assert info.overshoot_pct == pytest.approx(0.0, abs=1e-6)
    assert info.steady_offset == pytest.approx(0.05, abs=1e-4)
    ref = step_response(t, y, 1.0, 0.0, Config().control.metrics)
    assert ref.overshoot_pct == pytest.approx(5.0, abs=0.01)


def test_stepinfo_overshoot_of_a_second_order_response() -> None:
    zeta, wn = 0.5, 4.0
    t = np.arange(0.0, 10.0, 1e-3)
    wd = wn * math.sqrt(1 - zeta ** 2)
    y = 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta ** 2) * np.sin(wd * t))
    info = stepinfo(t, y, 0.0, 1.0, band=0.02, floor=0.0, final_window_s=1.0)
    assert info.overshoot_pct == pytest.approx(100 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta ** 2)), abs=0.05)


def test_no_reading_when_the_response_did_not_follow_the_step() -> None:
    t = np.arange(0.0, 5.0, 1e-3)
    y = np.full_like(t, 0.2) + 0.001 * np.sin(t)
    info = stepinfo(t, y, 0.2, 0.3, band=0.02, floor=0.0, final_window_s=1.0, r_step=0.1)
    assert math.isnan(info.overshoot_pct)
    assert math.isnan(info.settling_time_s)


def test_funnel_reading() -> None:
    t = np.arange(0.0, 5.0, 1e-3)
    r = np.full_like(t, 0.4)
    y = r - 0.2 * np.exp(-t)
    o = np.full_like(t, 0.3)
    ts, use = funnel_reading(t, y, r, o, 0.11)
    assert ts == pytest.approx(math.log(0.2 / 0.11), abs=2e-3)
    assert use == pytest.approx(100 * 0.2 / 0.3)
