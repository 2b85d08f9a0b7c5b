"""Issue 25 item 8 (part): isolated events on a straight line. PID recovers from entering a 0.15
slip patch within ~0.5 s (limit 2 s); the feed-forward alone never does (negative control: the
patch removes 15 % of the wheel speed, 0.057 m/s, which only feedback with integral action restores)."""

from __future__ import annotations

import math

from mrnc_eval.config import Config
from mrnc_eval.evaluation.disturbance import disturbance_study


def test_recovery_per_slip_event() -> None:
    cfg = Config()
    study = disturbance_study(("pid", "ff"), cfg.control, cfg.robot)
    assert study["pid"]["recovery_slip_on_s"] < 2.0
    assert study["pid"]["recovery_slip_off_s"] < 2.0
    assert math.isinf(study["ff"]["recovery_slip_on_s"])
    assert 0.0 < study["ff"]["min_funnel_margin"] < study["pid"]["min_funnel_margin"] < 1.0
