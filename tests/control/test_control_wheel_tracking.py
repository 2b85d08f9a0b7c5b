"""Issue 19 item 12: control replay on an ordinary robot log (IMU, wheel odometry, GNSS, no planned
path). Without a path the replay measures wheel-speed tracking against the skid-steer inverse
kinematics of the recorded cmd_vel (or the wheel odometry's twist); `--path FILE` supplies a path
after the fact. Logs are written with the project's writers from a closed-loop simulation whose
references and speeds are known."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.cli import main
from mrnc_eval.commands.control import run_log
from mrnc_eval.config import Config
from mrnc_eval.control.closed_loop import ClosedLoopTrace, run_closed_loop
from mrnc_eval.control.scenario import Scenario, scripted_scenario
from mrnc_eval.data import Trajectory, Twists, Waypoints
from mrnc_eval.evaluation.control_run import evaluate_trace
from mrnc_eval.io.trajectory_files import write_tum
from mrnc_eval.io.writers import LogWriter
from mrnc_eval.results import RunResult

T0 = 100.0  # log time of the run's start, s
SIDES = ("left", "right")


@pytest.fixture(scope="module")
def run() -> tuple[Scenario, ClosedLoopTrace]:
    """RAID driving the rounded-rectangle loop (straights and turns), recorded at 50 Hz."""
    cfg = Config()
    sc = scripted_scenario("loop", cfg.control, size_m=8.0)
    return sc, run_closed_loop(sc, cfg.control, cfg.robot, "raid", record_every=20)


def _write_log(path: Path, sc: Scenario, tr: ClosedLoopTrace, *, plan: bool = False, ground_truth: bool = False,
               cmd_vel_shift_s: float | None = 0.0, odom_twist: bool = True) -> Path:
    """A drive-train log of the run: wheel speeds, pump commands, cmd_vel (shifted in time by
    cmd_vel_shift_s; None: no cmd_vel), wheel odometry with its twist (pose: the run's own), and
    optionally the planned path and the ground truth."""
    cfg = Config()
    t = tr.t + T0
    quat = np.c_[np.zeros((t.size, 2)), np.sin(tr.yaw / 2), np.cos(tr.yaw / 2)]
    pose = Trajectory(t, np.c_[tr.x, tr.y, np.zeros_like(t)], quat)
    v_wheels = 0.5 * (tr.v_wheel_left + tr.v_wheel_right)
    w_wheels = (tr.v_wheel_right - tr.v_wheel_left) / cfg.robot.track_width_m
    zero = np.zeros_like(t)
    with LogWriter(path, fmt="mcap") as w:
        if plan:
            w.write_path("/plan", Waypoints(sc.waypoints_xy, frame_id="map"), t[0])
        if ground_truth:
            w.write_odometry("/ground_truth", pose)
        w.write_joint_state("/wheel_speeds", t, ["left_wheel", "right_wheel"],
                            np.c_[tr.v_wheel_left, tr.v_wheel_right] / cfg.robot.wheel_radius_m)
        w.write_joint_state("/pump_cmd", t, ["left_pump", "right_pump"], np.c_[tr.u_left, tr.u_right])
        if cmd_vel_shift_s is not None:
            w.write_twist_stamped("/cmd_vel", Twists(t + cmd_vel_shift_s, tr.cmd_v, tr.cmd_omega))
        w.write_odometry("/wheel_odom", replace(pose, name="wheel_odom"), "odom", "base_link",
                         linear_velocity=np.c_[v_wheels, zero, zero] if odom_twist else None,
                         angular_velocity=np.c_[zero, zero, w_wheels] if odom_twist else None)
    return path


def _metrics(result: RunResult) -> dict[tuple[str, str], float]:
    return {(m.group, m.name): float(m.value) for m in result.metrics}


def _rms(result: RunResult, side: str) -> float:
    return _metrics(result)[(f"control/recorded/{side}", "rms_error_mps")]


def test_without_a_path_the_replay_tracks_wheel_speeds_against_cmd_vel(run, tmp_path: Path) -> None:
    sc, tr = run
    cfg = Config()
    log = _write_log(tmp_path / "drive.mcap", sc, tr)
    result = run_log(log, cfg, tmp_path / "out", mode="replay")
    assert result.extra["replay"] == "wheel_speed"
    assert "wheel-speed tracking (no path)" in result.extra["labels"]["recorded"]
    assert "Wheel-speed tracking (no path)" in result.extra["definitions"][0]
    assert result.extra["roles"]["cmd_vel"] == "/cmd_vel"
    assert result.extra["t0_stamp_s"] == pytest.approx(T0, abs=1e-6)
    assert not any(m.group.endswith("/path") for m in result.metrics)  # nothing to measure cross-track against
    # the references are the simulator's own: the same IK of the same commands, the same slew (the
    # replay steps the slew at 50 Hz, the simulation at 1 kHz: apart by at most one 20 ms step of it)
    slew_step = cfg.control.kinematics.reference_accel_limit_mps2 * 0.02
    sim = evaluate_trace(tr, cfg.control)
    got = _metrics(result)
    for side in SIDES:
        v_ref = result.series[f"recorded_{side}_v_ref"]
        assert np.max(np.abs(v_ref - getattr(tr, f"v_ref_{side}"))) <= slew_step + 1e-9, side
        for key in ("rms_error_mps", "max_abs_error_mps", "iae"):
            assert got[(f"control/recorded/{side}", key)] == pytest.approx(sim[side][key], rel=0.05, abs=2e-3), key
        assert got[(f"control/recorded/{side}", "max_abs_command_rpm")] == pytest.approx(
            sim[side]["max_abs_command_rpm"], rel=1e-6)
        assert got[(f"control/recorded/{side}", "n_steps")] == sim[side]["n_steps"]


def test_summary_and_report_say_it_is_wheel_speed_tracking(run, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    from mrnc_eval.config import dump_config
    from mrnc_eval.reports.render import write_report
    from mrnc_eval.results import read_result

    sc, tr = run
    cfg = Config()
    log = _write_log(tmp_path / "drive.mcap", sc, tr)
    assert main(["control", str(log), "--out", str(tmp_path / "out")]) == 0
    printed = " ".join(capsys.readouterr().out.split())  # rich wraps lines
    assert "Recorded wheel-speed tracking (no path)" in printed
    assert "cmd_vel /cmd_vel" in printed
    result = read_result(tmp_path / "out" / "latest")
    written = write_report([result], tmp_path / "report", gates=cfg.gates, config_text=dump_config(cfg))
    html = written["html"].read_text()
    assert "Control: wheel-speed tracking (no path)" in html
    assert "Table II layout: control performance of the recorded run (wheel-speed tracking, no path)" in html


@pytest.mark.parametrize("wrong", ["cmd_vel 3 s late", "track width x2"])
def test_a_wrong_reference_shows_a_larger_tracking_error(run, tmp_path: Path, wrong: str) -> None:
    """Negative controls: references that do not belong to the run must not track as well."""
    sc, tr = run
    cfg = Config()
    right = run_log(_write_log(tmp_path / "drive.mcap", sc, tr), cfg, tmp_path / "ok", mode="replay")
    if wrong.startswith("cmd_vel"):
        wrong_log = _write_log(tmp_path / "late.mcap", sc, tr, cmd_vel_shift_s=3.0)
        bad = run_log(wrong_log, cfg, tmp_path / "bad", mode="replay")
        # evaluated only where cmd_vel exists; the series start there (the export's time origin)
        assert bad.extra["t0_stamp_s"] == pytest.approx(T0 + 3.0, abs=1e-6)
        assert any("outside the cmd_vel span not evaluated" in w for w in bad.warnings)
    else:
        wide = replace(cfg, robot=replace(cfg.robot, track_width_m=2.0 * cfg.robot.track_width_m))
        bad = run_log(tmp_path / "drive.mcap", wide, tmp_path / "bad", mode="replay")
    worst_right = max(_rms(right, s) for s in SIDES)
    worst_bad = max(_rms(bad, s) for s in SIDES)
    assert worst_bad > 2 * worst_right, (wrong, worst_right, worst_bad)


def test_without_cmd_vel_the_odometry_twist_gives_the_closed_form(run, tmp_path: Path) -> None:
    """Wheel odometry computes v = (vl + vr) / 2, omega = (vr - vl) / Lr from the wheels, so its
    inverse kinematics gives the wheel speeds back exactly (error 0, and said to be by construction);
    with a track Lr' the error of each side is omega (Lr' - Lr) / 2 in size."""
    sc, tr = run
    cfg = Config()
    log = _write_log(tmp_path / "odom_only.mcap", sc, tr, cmd_vel_shift_s=None)
    result = run_log(log, cfg, tmp_path / "out", mode="replay")
    assert result.extra["roles"]["wheel_odom"] == "/wheel_odom"
    assert "cmd_vel" not in result.extra["roles"]
    assert any("by construction" in w for w in result.warnings)
    for side in SIDES:
        assert _rms(result, side) < 1e-9
    factor = 1.25
    wide = replace(cfg, robot=replace(cfg.robot, track_width_m=factor * cfg.robot.track_width_m))
    skewed = run_log(log, wide, tmp_path / "wide", mode="replay")
    omega = (tr.v_wheel_right - tr.v_wheel_left) / cfg.robot.track_width_m
    expected = (factor - 1.0) * cfg.robot.track_width_m / 2 * float(np.sqrt(np.mean(omega ** 2)))
    for side in SIDES:
        assert _rms(skewed, side) == pytest.approx(expected, rel=1e-6)


def test_path_file_reproduces_the_replay_of_the_log_with_its_plan(run, tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    sc, tr = run
    with_plan = _write_log(tmp_path / "with_plan.mcap", sc, tr, plan=True, ground_truth=True)
    without = _write_log(tmp_path / "without_plan.mcap", sc, tr, ground_truth=True)
    want = _metrics(run_log(with_plan, Config(), tmp_path / "a", mode="replay"))
    wp = sc.waypoints_xy
    tum = tmp_path / "plan.tum"
    write_tum(tum, Trajectory(T0 + np.arange(len(wp), dtype=float), np.c_[wp, np.zeros(len(wp))],
                              np.tile([0.0, 0.0, 0.0, 1.0], (len(wp), 1))))
    assert main(["control", str(without), "--mode", "replay", "--path", str(tum), "--out", str(tmp_path / "b"),
                 "--json"]) == 0
    body = json.loads(capsys.readouterr().out)
    got = {(f"control/recorded/{r['side']}", name): float("nan" if value is None else value)  # inf: null
           for r in body["results"] if r["controller"] == "recorded" for name, value in r["stats"].items()}
    assert set(got) == set(want)
    assert any(k[0].endswith("/path") for k in want)  # cross-track and completion, as with /plan
    for key, value in want.items():  # --json stats: NaN and infinity ("not settled") are both null
        value = value if np.isfinite(value) else float("nan")
        assert got[key] == pytest.approx(value, rel=1e-6, abs=1e-9, nan_ok=True), key
    saved = json.loads((Path(body["meta"]["run_dir"]) / "result.json").read_text())
    assert saved["extra"]["replay"] == "path"
    assert saved["extra"]["roles"]["path"] == f"{tum} (--path)"


@pytest.mark.parametrize(("name", "text", "problem"), [
    ("plan.tum", "0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n2 2 0 0 0 0 1\n", "line 3 has 7 fields, expected 8"),
    ("plan.csv", "x,y\n0,0\n1,one\n", "line 3: 'one' is not a finite number"),
    ("plan.csv", "0,0\n1,1,0,5\n", "line 2 has 4 fields"),
    ("plan.csv", "x,y\n0,0\n", "at least 2 waypoints"),
    ("plan.json", "[]", "unknown waypoint file .json"),
])
def test_a_bad_path_file_is_one_error_naming_file_and_line(run, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                          name: str, text: str, problem: str) -> None:
    sc, tr = run
    log = _write_log(tmp_path / "drive.mcap", sc, tr)
    bad = tmp_path / name
    bad.write_text(text)
    out = tmp_path / "out"
    assert main(["control", str(log), "--path", str(bad), "--out", str(out)]) == 4
    err = capsys.readouterr().err
    assert f"{bad}: " in err, err
    assert problem in err, err
    assert len(err.strip().splitlines()) == 1
    assert not out.exists() or not any(out.iterdir())  # no partial output


def test_a_log_with_neither_path_nor_twist_says_what_it_needs(run, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    _, tr = run
    cfg = Config()
    log = tmp_path / "wheels_only.mcap"
    with LogWriter(log, fmt="mcap") as w:
        w.write_joint_state("/wheel_speeds", tr.t, ["left_wheel", "right_wheel"],
                            np.c_[tr.v_wheel_left, tr.v_wheel_right] / cfg.robot.wheel_radius_m)
    assert main(["control", str(log), "--out", str(tmp_path / "out")]) == 4
    err = capsys.readouterr().err
    for needed in ("--path FILE", "cmd_vel", "io.roles.path"):
        assert needed in err, err


def test_csv_waypoints_with_or_without_a_header(tmp_path: Path) -> None:
    from mrnc_eval.io.waypoint_files import read_waypoints

    plain = tmp_path / "plain.csv"
    plain.write_text("# planned path\n0,0\n1.5,0.25\n\n3,1,0\n")
    named = tmp_path / "named.csv"
    named.write_text("stamp,y,x,z\n0,0,0,0\n1,0.25,1.5,0\n2,1,3,0\n")
    want = np.array([[0.0, 0.0], [1.5, 0.25], [3.0, 1.0]])
    for path in (plain, named):
        np.testing.assert_array_equal(read_waypoints(path).xy, want)


def test_replay_refuses_controllers_and_prints_not_settled(capsys: pytest.CaptureFixture[str],
                                                          tmp_path: Path) -> None:
    from mrnc_eval.cli import main as cli_main
    from mrnc_eval.reports.control_tables import replay_cell as _replay_cell

    assert cli_main(["control", str(tmp_path / "any.mcap"), "--mode", "replay", "--controllers", "pid"]) == 2
    assert "--controllers chooses the controllers of --mode simulate and sweep" in capsys.readouterr().err
    assert _replay_cell(float("inf")) == "not settled"  # the legend's words, not "inf"
    assert _replay_cell(float("nan")) is None
    assert _replay_cell(1.5) == 1.5
