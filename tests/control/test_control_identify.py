"""Issue 25 item 9: the drive identified from a log. Logs of closed-loop runs on three known plants
(PID on the rounded-rectangle loop; pump commands at the 1 kHz control rate, held between messages as
a pump holds them; wheel speeds at 50 Hz with 2 mm/s noise): gain, dead band and time constant within
10 %, delay within 5 ms. Negative control: the same commands recorded at 50 Hz but read as held (the
1 kHz command between two 50 Hz samples is no step) miss the delay by more than 5 ms. A log without
commands is a clear input error."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.cli import main
from mrnc_eval.config import Config, load_config
from mrnc_eval.control.closed_loop import ClosedLoopTrace, run_closed_loop
from mrnc_eval.control.config import DriveConfig
from mrnc_eval.control.identify import DriveEstimate, IdentificationError, identify_side
from mrnc_eval.control.scenario import scripted_scenario
from mrnc_eval.io.writers import LogWriter

PLANTS = [DriveConfig(gain_mps_per_rpm=1.1 / 3000, tau_s=0.4, delay_s=0.04, dead_band_rpm=60.0),
          DriveConfig(gain_mps_per_rpm=0.85 / 3000, tau_s=0.25, delay_s=0.07, dead_band_rpm=120.0),
          DriveConfig(gain_mps_per_rpm=1.2 / 3000, tau_s=0.7, delay_s=0.02, dead_band_rpm=30.0)]
# the loop applies a command one control period (1 ms) after it is computed: the true delay is d + 1 ms
PERIOD = 1e-3
WHEEL = 20  # wheel speeds at 50 Hz


def _run(drive: DriveConfig) -> ClosedLoopTrace:
    cfg = Config()
    c = replace(cfg.control, plant=replace(cfg.control.plant, left=drive, right=drive))
    return run_closed_loop(scripted_scenario("loop", c, size_m=8.0), c, cfg.robot, "pid", record_every=1)


@pytest.fixture(scope="module")
def runs() -> list[ClosedLoopTrace]:
    return [_run(d) for d in PLANTS]


def _close(e: DriveEstimate, d: DriveConfig) -> dict[str, bool]:
    return {"gain": abs(e.gain_mps_per_rpm / d.gain_mps_per_rpm - 1) < 0.1,
            "dead_band": abs(e.dead_band_rpm / d.dead_band_rpm - 1) < 0.1,
            "tau": abs(e.tau_s / d.tau_s - 1) < 0.1,
            "delay": abs(e.delay_s - (d.delay_s + PERIOD)) < 0.005}


def test_identifies_three_plants(runs) -> None:
    for drive, tr in zip(PLANTS, runs, strict=True):
        for v, u in ((tr.v_wheel_left, tr.u_left), (tr.v_wheel_right, tr.u_right)):
            e = identify_side(tr.t[::WHEEL], v[::WHEEL], tr.t, u)
            assert all(_close(e, drive).values()), (drive, e)
            # the reported uncertainty is honest: each estimate within 4 sigma (+ 1 ms grid) of the truth
            assert abs(e.gain_mps_per_rpm - drive.gain_mps_per_rpm) < 4 * e.gain_sd + 0.01 * drive.gain_mps_per_rpm
            assert e.delay_sd < 0.005


def test_the_wrong_command_model_misses_the_delay(runs) -> None:
    tr, drive = runs[0], PLANTS[0]
    e = identify_side(tr.t[::WHEEL], tr.v_wheel_left[::WHEEL], tr.t[::WHEEL], tr.u_left[::WHEEL], signal="held")
    assert not _close(e, drive)["delay"]
    # read as sampled (linear between samples) the 50 Hz commands identify the plant again
    e = identify_side(tr.t[::WHEEL], tr.v_wheel_left[::WHEEL], tr.t[::WHEEL], tr.u_left[::WHEEL], signal="sampled")
    assert all(_close(e, drive).values()), e


def test_no_excitation_is_a_typed_error() -> None:
    t = np.arange(0.0, 10.0, 0.02)
    with pytest.raises(IdentificationError, match="hardly change"):
        identify_side(t, np.full(t.size, 0.3), t, np.full(t.size, 1000.0))


def _write(path: Path, tr: ClosedLoopTrace, *, commands: bool = True) -> Path:
    cfg = Config()
    t = tr.t + 100.0
    with LogWriter(path, fmt="mcap") as w:
        w.write_joint_state("/wheel_speeds", t[::WHEEL], ["left_wheel", "right_wheel"],
                            np.c_[tr.v_wheel_left, tr.v_wheel_right][::WHEEL] / cfg.robot.wheel_radius_m)
        if commands:  # at the control rate
            w.write_joint_state("/pump_cmd", t, ["left_pump", "right_pump"], np.c_[tr.u_left, tr.u_right])
    return path


def test_identify_cli_writes_a_plant_the_simulation_runs_on(runs, tmp_path: Path, capsys) -> None:
    log = _write(tmp_path / "drive.mcap", runs[1])
    assert main(["control", str(log), "--mode", "identify", "--json", "--out", str(tmp_path / "res")]) == 0
    body = json.loads(capsys.readouterr().out)
    found = {r["side"]: DriveEstimate(**r["stats"]) for r in body["results"]}
    assert set(found) == {"left", "right"}
    for e in found.values():
        assert all(_close(e, PLANTS[1]).values()), e
    plant_file = body["meta"]["plant_file"]
    cfg = load_config(Path(plant_file))
    assert cfg.control.plant.left.dead_band_rpm == pytest.approx(120.0, rel=0.1)
    lo, hi = cfg.control.sweep.gain_mismatch
    assert lo < 0.85 - 1 < hi  # the sweep's ranges cover the identified plant
    assert main(["control", "--mode", "simulate", "--controllers", "pid", "--config", plant_file,
                 "--json", "--out", str(tmp_path / "sim")]) == 0
    sim = json.loads(capsys.readouterr().out)
    left = next(r for r in sim["results"] if r["name"] == "pid/left")
    assert left["stats"]["safety_stops"] == 0


def test_identify_without_commands_is_a_clear_error(runs, tmp_path: Path, capsys) -> None:
    log = _write(tmp_path / "speeds_only.mcap", runs[0], commands=False)
    assert main(["control", str(log), "--mode", "identify", "--out", str(tmp_path / "res")]) == 4
    err = capsys.readouterr().err
    assert "speeds_only.mcap" in err
    assert "pump commands" in err
    assert not (tmp_path / "res").exists() or not any((tmp_path / "res").iterdir())
