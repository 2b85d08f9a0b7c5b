"""Issue 25 item 1: RAID's output unit is a declared choice; its interior gain against closed forms
and where its local gain meets PID's k_p and the drive's P-law stability limit; loop margins of the
linear laws against a closed form."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from mrnc_eval.config import Config
from mrnc_eval.control.margins import critical_p_gain, loop_summary, margins, pi_response, plant_response
from mrnc_eval.control.raid import interior_gain, local_gain, output_units, rbf_centres, rbf_norms


def _a(c, v: float, phi: float) -> float:
    n, n2 = rbf_norms(v, rbf_centres(c), c.raid.gamma)
    return phi ** 4 * n + n2 + 1.0


def test_interior_gain_closed_form_per_unit() -> None:
    c = Config().control
    ob, beta, v = c.funnel.o_b_mps, c.raid.beta, 0.38
    literal = interior_gain(c, v=v, phi=0.0)
    assert literal == pytest.approx(beta / 2 + _a(c, v, 0.0) / ob ** 2)
    assert local_gain(c, e_over_o=0.0, v=v, phi=0.0) == pytest.approx(literal, rel=1e-6)
    ff = replace(c, raid=replace(c.raid, output_unit="feedforward_gain"))
    assert output_units(ff) == (3000.0, 1.0)
    assert interior_gain(ff, v=v, phi=0.0) == pytest.approx(3000.0 * literal)
    norm = replace(c, raid=replace(c.raid, output_unit="error_over_floor"))
    assert interior_gain(norm, v=v, phi=0.0) == pytest.approx((beta / 2 + _a(c, v, 0.0)) / ob)


def test_local_gain_meets_pid_and_the_stability_limit_near_the_barrier() -> None:
    c = Config().control
    s = loop_summary(c, 0.38)
    # literal reading: the loop is nearly open until |e| is ~90 % of the funnel (issue 25: ~0.95-0.965)
    assert 0.85 < s["raid_e_over_o_at_pid_kp"] < s["raid_e_over_o_at_stability_limit"] < 0.99
    assert local_gain(c, e_over_o=float(s["raid_e_over_o_at_pid_kp"]), v=0.38, phi=0.0) == pytest.approx(4800.0,
                                                                                                          rel=1e-3)


def test_p_law_gain_margin_closed_form() -> None:
    """K e^{-sd}/(tau s + 1) under a P law: phase -180 deg where atan(w tau) + w d = pi; k_crit =
    sqrt(1 + (w tau)^2) / K."""
    drive = Config().control.plant.left
    lo, hi = 1.0, 200.0
    for _ in range(100):
        w = 0.5 * (lo + hi)
        if math.atan(w * drive.tau_s) + w * drive.delay_s < math.pi:
            lo = w
        else:
            hi = w
    want = math.sqrt(1 + (w * drive.tau_s) ** 2) / drive.gain_mps_per_rpm
    assert critical_p_gain(drive) == pytest.approx(want, rel=2e-3)
    m = margins(pi_response(2.0 * want, 0.0) * plant_response(drive))
    assert m.gain_margin == pytest.approx(0.5, rel=2e-3)  # twice the critical gain: unstable


def test_bode_agrees_with_the_margins() -> None:
    from mrnc_eval.control.margins import bode, loop_margins

    c = Config().control
    g = interior_gain(c, v=0.38, phi=0.0)
    _, loops = bode(c, g, points=20000)
    m = loop_margins(c, g)["pid"]
    phase = np.unwrap(np.angle(loops["pid"]))
    k = int(np.flatnonzero(phase <= -np.pi)[0])
    assert 1.0 / np.abs(loops["pid"][k]) == pytest.approx(m.gain_margin, rel=0.01)
    assert np.all(np.abs(loops["raid"]) < 1.0)  # the literal reading: RAID's loop gain never reaches 1
