"""Issue 25 item 4: the per-step funnel and FOPTC's prescribed-time clock restart on a step of a
slew-limited reference (ramp-aware detector). The old per-sample rule (one sample must change the
reference by more than 1e-3 m/s) never fires under the 0.3 m/s^2 slew: it is the negative control."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from mrnc_eval.config import Config
from mrnc_eval.control.closed_loop import ST_RESTARTS, run_closed_loop
from mrnc_eval.control.config import ControlConfig
from mrnc_eval.control.controllers import make_controller
from mrnc_eval.control.raid import funnel
from mrnc_eval.control.scenario import paper_circle_scenario

DT = 1e-3
SLEW = 0.3  # m/s^2, the default reference slew


def _cfg(detector: str) -> ControlConfig:
    c = Config().control
    return replace(c, steps=replace(c.steps, detector=detector), funnel=replace(c.funnel, anchor="reference_change"))


def _slewed_step(name: str, cfg: ControlConfig, t_step: float = 5.0) -> tuple[object, np.ndarray, np.ndarray]:
    """0.2 -> 0.35 m/s at t_step, slewed at 0.3 m/s^2 (ends at t_step + 0.5 s), on a first-order drive
    (tau 0.3 s) 5 % weaker than the controllers' 1/3000 (m/s)/RPM, so feedback has work to do."""
    ctrl = make_controller(name, cfg)
    r = y = 0.2
    n = int(10.0 / DT)
    o, u = np.zeros(n), np.zeros(n)
    for k in range(n):
        t = k * DT
        target = 0.2 if t < t_step else 0.35
        r += float(np.clip(target - r, -SLEW * DT, SLEW * DT))
        u[k], _ = ctrl.step(t, r, 0.0, y, DT)
        y += (u[k] / 3150.0 - y) * DT / 0.3
        o[k] = ctrl.funnel(t)
    return ctrl, o, u


@pytest.mark.parametrize("name", ["raid", "foptc", "pid"])
def test_funnel_restarts_at_the_end_of_a_slewed_step(name: str) -> None:
    cfg = _cfg("ramp")
    ctrl, o, _ = _slewed_step(name, cfg)
    f = cfg.funnel
    assert ctrl.restarts == 1  # type: ignore[attr-defined]
    # 1 s after the ramp ended (t = 6.5 s) the funnel is o(1 s), not o(6.5 s)
    assert o[6500] == pytest.approx(funnel(1.0, f.o_ov_mps, f.o_b_mps, f.o_star_per_s)[0], abs=1e-3)
    assert o[6500] > funnel(6.5, f.o_ov_mps, f.o_b_mps, f.o_star_per_s)[0] + 0.05


def test_the_old_per_sample_rule_fails_the_restart_test() -> None:
    """Negative control: under the default slew the per-sample rule never restarts."""
    cfg = _cfg("per_sample")
    ctrl, o, _ = _slewed_step("raid", cfg)
    f = cfg.funnel
    assert ctrl.restarts == 0  # type: ignore[attr-defined]
    assert o[6500] != pytest.approx(funnel(1.0, f.o_ov_mps, f.o_b_mps, f.o_star_per_s)[0], abs=1e-3)


def test_foptc_prescribed_time_clock_restarts_and_changes_the_command() -> None:
    """FOPTC's gain k0 + c h / (T - t_s) falls back to k0 + c h / T after a step: its command right
    after the ramp differs from the non-restarting clock's (a fixed PI after T - delta)."""
    _, _, u_ramp = _slewed_step("foptc", _cfg("ramp"))
    _, _, u_old = _slewed_step("foptc", _cfg("per_sample"))
    before = slice(0, 4900)
    after = slice(5500, 6200)
    assert np.max(np.abs(u_ramp[before] - u_old[before])) < 1e-9  # same until the step
    assert np.max(np.abs(u_ramp[after] - u_old[after])) > 1.0  # RPM


def test_closed_loop_counts_restarts_per_side_on_the_default_drive() -> None:
    c = Config()
    scen = paper_circle_scenario(c.control)
    counts = {}
    for det in ("ramp", "per_sample"):
        cc = replace(c.control, steps=replace(c.control.steps, detector=det))
        tr = run_closed_loop(scen, cc, c.robot, "foptc", duration_s=6.0, record_every=20)
        assert tr.full_rate_stats is not None
        counts[det] = tr.full_rate_stats[:, ST_RESTARTS]
    assert np.all(counts["ramp"] >= 1)  # the start-up step, both sides
    assert np.all(counts["per_sample"] == 0)
