"""A simulated drive that RAID's safety constraint stops mid-path (ninth session): asked for 2 m/s with the
actuator clamped at 4000 RPM (about 1.4 m/s reachable), the machine stopped after 4.7 m and the log stood
still for the rest without a word. `simulate` now warns with the stop's time in the log's clock (the
standing start's delay included) and <log>.errors.json records it; a speed the actuator reaches (the
negative control) says nothing."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.cli import main

FAST = ["--set", "control.pure_pursuit.desired_speed_mps={v}", "--set", "control.pure_pursuit.max_speed_mps={v}",
        "--set", "control.pure_pursuit.speed_cap=false", "--set", "control.actuator.u_max_rpm=4000"]


def _simulate(tmp_path: Path, speed: float, capsys: pytest.CaptureFixture[str]) -> tuple[Path, list[str]]:
    out = tmp_path / f"line_{speed:g}.mcap"
    assert main(["simulate", str(out), "--profile", "field", "--lidar", "os0-32", "--columns", "512",
                 "--duration", "9", "--scene", "open_field", "--path", "line", "--seed", "40",
                 *[a.format(v=speed) for a in FAST]]) == 0
    return out, [ln for ln in capsys.readouterr().err.splitlines() if "stopped at" in ln]


def test_a_safety_stop_in_the_simulated_drive_is_said(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log, warnings = _simulate(tmp_path, 2.0, capsys)
    assert warnings
    assert "RAID's safety constraint" in warnings[0]
    assert "control.actuator.u_max_rpm" in warnings[0]
    stops = json.loads(log.with_name("line_2.errors.json").read_text())["drive"]["safety_stops"]
    t_stop = min(s["t_s"] for s in stops)
    gt = np.loadtxt(log.with_name("line_2.gt.tum"))
    t, speed = gt[1:, 0] - gt[0, 0], np.linalg.norm(np.diff(gt[:, 1:3], axis=0), axis=1) / np.diff(gt[:, 0])
    assert speed[t < t_stop].max() > 1.0  # driving before the stop (log clock)
    assert speed[t > t_stop + 2.0].max() < 0.05  # standing two seconds after it
    _, calm = _simulate(tmp_path, 1.0, capsys)
    assert not calm  # the negative control: 1 m/s is within the clamp
    assert "drive" not in json.loads((tmp_path / "line_1.errors.json").read_text())


def _loop_stops(speed: float) -> list[dict[str, object]]:
    """The claims matrix's open loop (20 x 12 m, 4 m corners) driven by RAID at `speed` (m/s), field seed 3."""
    from mrnc_eval.config import Config, replace_paths
    from mrnc_eval.control.closed_loop import run_closed_loop
    from mrnc_eval.control.scenario import scripted_scenario

    cfg = replace_paths(Config(), {"control.pure_pursuit.desired_speed_mps": speed,
                                   "control.pure_pursuit.max_speed_mps": speed,
                                   "control.pure_pursuit.speed_cap": False, "control.actuator.u_max_rpm": 4000.0})
    trace = run_closed_loop(scripted_scenario("loop", cfg.control, size_m=20.0), cfg.control, cfg.robot, "raid",
                            duration_s=40.0, seed=3)
    return [e for e in trace.events if e.get("kind") == "safety_stop"]


def test_a_turn_the_drive_cannot_follow_is_named_as_such(tmp_path: Path) -> None:
    """Tenth session: the claims matrix's loop at 1 m/s stopped in its first corners below the clamp
    (every loop cell was a 13 m drive and a stand); the hint named the clamp, which was not the cause.
    The benchmark's 0.7 m/s drives the loop without a stop (the control for the turn's cause)."""
    from mrnc_eval.commands.simulate import drive_warnings

    stops = _loop_stops(1.0)
    assert stops
    assert {s["cause"] for s in stops} == {"barrier"}
    assert min(float(s["t_s"]) for s in stops) < 20.0  # in the first corners, not at the path's end
    (tmp_path / "loop.errors.json").write_text(json.dumps({"drive": {"safety_stops": stops}}))
    warning = drive_warnings(tmp_path / "loop.mcap")[0]
    assert "a speed or a turn the drive cannot follow" in warning
    assert "u_max_rpm" not in warning  # the clamp was not reached
    assert _loop_stops(0.7) == []
