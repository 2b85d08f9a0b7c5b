"""Control chain pieces against closed forms, the paper scenario's geometry, the baselines'
defining properties, safety stops, and replay of a written log against the simulation."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from mrnc_eval.config import Config
from mrnc_eval.control.closed_loop import run_closed_loop
from mrnc_eval.control.config import ActuatorConfig, FunnelConfig, MetricsConfig, PurePursuitConfig
from mrnc_eval.control.controllers import make_controller
from mrnc_eval.control.plant import body_step, drive_step
from mrnc_eval.control.pure_pursuit import PurePursuit, pp_step, pure_pursuit_params
from mrnc_eval.control.scenario import paper_circle_scenario, scripted_scenario
from mrnc_eval.evaluation.control_metrics import cross_track, recovery_time, tracking_metrics

# ---- plant -------------------------------------------------------------------------------

def test_drive_step_is_the_discrete_first_order_lag_with_dead_band_and_slip() -> None:
    tau, dt, gain, dz, slip, u = 0.4, 1e-3, 1 / 3000, 60.0, 0.1, 900.0
    a = math.exp(-dt / tau)
    v = 0.0
    for n in range(1, 2001):
        v = drive_step(v, u, slip, gain, a, dz)
        if n in (1, 400, 2000):  # exact discrete solution of the lag
            assert v == pytest.approx(gain * (1 - slip) * (u - dz) * (1 - a ** n), rel=1e-9)
    assert drive_step(0.0, 59.0, 0.0, gain, a, dz) == 0.0
    assert drive_step(0.0, -59.0, 0.0, gain, a, dz) == 0.0
    assert drive_step(0.0, -900.0, 0.0, gain, a, dz) == pytest.approx(-(1 - a) * gain * 840.0)


def test_body_step_drives_the_icr_circle() -> None:
    track, vl, vr, dt = 1.6, 0.3, 0.5, 1e-3
    radius = track / 2 * (vr + vl) / (vr - vl)  # 3.2 m, left turn
    period = 2 * math.pi * radius / (0.5 * (vl + vr))
    x, y, yaw = 0.0, 0.0, 0.0
    n = int(round(period / dt))
    for _ in range(n):
        x, y, yaw, v, w = body_step(x, y, yaw, vl, vr, track, dt)
    assert v == pytest.approx(0.4)
    assert w == pytest.approx(0.2 / track)
    # exact arc integration: back at the start after one period (up to the rounding of n)
    assert math.hypot(x, y) < 0.4 * abs(period - n * dt) + 1e-9
    x, y, yaw, *_ = body_step(0.0, 0.0, 0.0, vl, vr, track, period / 2)
    assert (x, y) == pytest.approx((0.0, 2 * radius), abs=1e-9)


# ---- pure pursuit ------------------------------------------------------------------------

def _pp(x, y, yaw, wp, literal, L=1.0):
    cfg = PurePursuitConfig(lookahead_m=L, max_speed_mps=10.0, curvature="paper_literal" if literal else "standard",
                            speed_cap=False, approach_distance_m=0.0)
    return pp_step(x, y, yaw, 0.0, np.asarray(wp, float), 0, pure_pursuit_params(cfg, 1.6, 10.0))


def test_curvature_standard_and_paper_literal() -> None:
    wp = [[0.0, 0.0], [0.0, 20.0]]
    # robot at (0.6, 0) facing +y: the carrot is where the 1 m circle meets x = 0, at (0, 0.8)
    v, w, _, done, cx, cy = _pp(0.6, 0.0, math.pi / 2, wp, False)
    assert (cx, cy) == pytest.approx((0.0, 0.8))
    assert not done
    alpha = math.atan2(0.8, -0.6) - math.pi / 2  # left of the heading
    assert w / v == pytest.approx(2 * math.sin(alpha) / 1.0)  # Coulter, D = |carrot| = 1
    v2, w2, *_ = _pp(0.6, 0.0, math.pi / 2, wp, True)
    # printed form: delta = atan(2 L sin(alpha) / D), kappa = 2 tan(delta) / D = 4 L sin(alpha) / D^2
    assert w2 / v2 == pytest.approx(4 * math.sin(alpha))


def test_pure_pursuit_index_never_jumps_back_on_the_paper_circle() -> None:
    cfg = Config()
    sc = paper_circle_scenario(cfg.control)
    tr = run_closed_loop(sc, cfg.control, cfg.robot, "pid", record_every=20)
    pp = PurePursuit(sc.waypoints_xy, cfg.control.pure_pursuit, cfg.robot.track_width_m, cfg.robot.max_speed_mps)
    idx = []
    for x, y, yaw in zip(tr.x, tr.y, tr.yaw, strict=True):
        pp.step(x, y, yaw)
        idx.append(pp.index)
    # start and end coincide on the closed circle: the index must not skip to the last segment
    assert idx[0] == 0
    assert np.all(np.diff(idx) >= 0)
    assert np.all(np.diff(idx) <= 1)
    assert idx[-1] == len(sc.waypoints_xy) - 2
    assert pp.done
    assert tr.cmd_v[-1] == 0.0
    assert tr.cmd_omega[-1] == 0.0


# ---- scenario ----------------------------------------------------------------------------

def test_paper_scenario_matches_the_papers_figure() -> None:
    cfg = Config()
    sc = paper_circle_scenario(cfg.control)
    cx, cy = cfg.control.scenario.centre_xy_m
    wp = sc.waypoints_xy
    assert wp.shape == (9, 2)
    assert np.allclose(wp[0], wp[-1])
    assert np.allclose(np.hypot(wp[:, 0] - cx, wp[:, 1] - cy), 5.0)
    for px, py in ((2, -8), (2, -4), (7, -1)):  # the paper's slip locations lie on the 5 m circle
        assert math.hypot(px - cx, py - cy) == pytest.approx(5.0, abs=0.03)
    assert np.hypot(*(wp[1] - (2, -8))) < 0.1
    assert np.hypot(*(wp[2] - (2, -4))) < 0.1
    # clockwise: the signed area is negative, so the left side is the outer, faster one
    area = 0.5 * np.sum(wp[:-1, 0] * wp[1:, 1] - wp[1:, 0] * wp[:-1, 1])
    assert area < 0


def test_closed_loop_is_deterministic_and_takes_bare_waypoints() -> None:
    cfg = Config()
    wp = scripted_scenario("line", cfg.control, size_m=4.0).waypoints_xy
    a = run_closed_loop(wp, cfg.control, cfg.robot, "raid", seed=3)
    b = run_closed_loop(wp, cfg.control, cfg.robot, "raid", seed=3)
    c = run_closed_loop(wp, cfg.control, cfg.robot, "raid", seed=4)
    assert np.array_equal(a.v_wheel_left, b.v_wheel_left)
    assert np.array_equal(a.x, b.x)
    assert not np.array_equal(a.v_wheel_left, c.v_wheel_left)
    assert a.completed
    assert abs(a.x[-1] - 4.0) < 0.3
    assert abs(a.y[-1]) < 0.05
    assert a.completion_time_s == pytest.approx(a.t[-1] - 2.0, abs=0.01)  # 2 s recorded after the goal


# ---- controllers -------------------------------------------------------------------------

def _drive(ctrl, refs, dt=1e-3, tau=0.4, gain=1 / 3000, dz=60.0):
    v, out = 0.0, []
    for k, r in enumerate(refs):
        u, ok = ctrl.step(k * dt, r, 0.0, v, dt)
        v += dt / tau * (gain * np.sign(u) * max(abs(u) - dz, 0.0) - v)
        out.append((v, u, ok))
    return np.asarray(out)


def test_apc_holds_its_increment_at_10_hz_and_removes_the_steady_state_error() -> None:
    cfg = Config().control
    out = _drive(make_controller("apc", cfg), np.full(30000, 0.3))
    u = out[:, 1]
    changes = np.flatnonzero(np.diff(u) != 0) + 1
    assert np.all(changes % 100 == 0)  # updates only every 100 samples (10 Hz at 1 kHz)
    assert abs(out[-1000:, 0].mean() - 0.3) < 2e-3  # incremental law: no offset despite the dead band


def test_feedback_only_clamp_lets_the_total_exceed_the_limit() -> None:
    cfg = Config().control
    for applies, above in (("total", False), ("feedback", True)):
        c = replace(cfg, actuator=ActuatorConfig(saturation_applies_to=applies))
        u, ok = make_controller("pid", c).step(0.0, 0.5, 0.0, 0.0, 1e-3)  # f = 1500 RPM alone
        assert ok
        assert (u > 1250.0) == above


def test_raid_reports_a_safety_stop_at_the_barrier() -> None:
    cfg = Config().control
    raid = make_controller("raid", cfg)
    u, ok = raid.step(0.0, 0.3, 0.0, 0.3 - 0.29, 1e-3)  # |e| = 0.29 < o(0) = 0.30: finite, pushes up hard
    assert ok
    assert u > 3000 * 0.3
    u, ok = raid.step(1e-3, 0.3, 0.0, 0.3 - 0.31, 1e-3)  # beyond the barrier
    assert not ok
    assert u == 0.0
    # in the closed loop: a funnel narrower than the start-up error stops both sides, no crash
    tight = replace(cfg, funnel=FunnelConfig(o_ov_mps=0.02, o_b_mps=0.01))
    tr = run_closed_loop(scripted_scenario("line", cfg), tight, Config().robot, "raid", duration_s=5.0)
    assert {e["side"] for e in tr.events} == {"left", "right"}
    stop = min(e["t_s"] for e in tr.events)
    assert np.all(tr.u_left[tr.t > stop + 1e-3] == 0.0)
    assert tr.t[-1] == pytest.approx(5.0, abs=2e-3)


# ---- metrics -----------------------------------------------------------------------------

def test_recovery_time_after_a_slip_event_is_the_exponential_decay_time() -> None:
    tau, t = 0.5, np.arange(0, 20, 1e-3)
    err = np.where(t < 5, 0.0, 0.1 * np.exp(-(t - 5) / tau))
    slip = (t >= 5).astype(float)
    assert recovery_time(t, err, slip, band=0.02, hold_s=1.0) == pytest.approx(tau * math.log(5), abs=2e-3)
    assert math.isinf(recovery_time(t, np.full_like(t, 0.05), slip, band=0.02))


def test_cross_track_sign_and_integral_errors() -> None:
    wp = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    cte, heading = cross_track(np.array([5.0, 5.0, 11.0]), np.array([0.5, -0.25, 5.0]), wp)
    assert cte == pytest.approx([0.5, -0.25, -1.0])
    assert heading == pytest.approx([0.0, 0.0, math.pi / 2])
    tau, t = 0.4, np.arange(0, 10, 1e-4)
    y = 1 - np.exp(-t / tau)
    m = tracking_metrics(t, np.ones_like(t), y, np.zeros_like(t), np.full_like(t, 2.0), u_max=1250.0, slip=None,
                         cfg=MetricsConfig())
    assert m["iae"] == pytest.approx(tau, rel=1e-3)
    assert m["ise"] == pytest.approx(tau / 2, rel=1e-3)
    assert m["itae"] == pytest.approx(tau ** 2, rel=1e-3)
    assert m["funnel_violations"] == 0


# ---- replay ------------------------------------------------------------------------------

def test_replay_of_a_written_log_reproduces_the_simulated_tracking(tmp_path) -> None:
    from mrnc_eval.commands.control import run_log
    from mrnc_eval.data import Trajectory, Waypoints
    from mrnc_eval.evaluation.control_run import evaluate_trace
    from mrnc_eval.io.writers import LogWriter

    cfg = Config()
    sc = scripted_scenario("loop", cfg.control, size_m=8.0)
    tr = run_closed_loop(sc, cfg.control, cfg.robot, "raid", record_every=20)  # 50 Hz, as logs often are
    t = tr.t + 100.0
    quat = np.c_[np.zeros((t.size, 2)), np.sin(tr.yaw / 2), np.cos(tr.yaw / 2)]
    log = tmp_path / "run.mcap"
    r = cfg.robot.wheel_radius_m
    with LogWriter(log, fmt="mcap") as w:
        w.write_path("/plan", Waypoints(sc.waypoints_xy, frame_id="map"), t[0])
        w.write_odometry("/ground_truth", Trajectory(t, np.c_[tr.x, tr.y, np.zeros_like(t)], quat))
        w.write_joint_state("/wheel_speeds", t, ["left_wheel", "right_wheel"],
                            np.c_[tr.v_wheel_left, tr.v_wheel_right] / r)
        w.write_joint_state("/pump_cmd", t, ["left_pump", "right_pump"], np.c_[tr.u_left, tr.u_right])
    result = run_log(log, cfg, tmp_path / "out", mode="replay")
    got = {(m.group, m.name): m.value for m in result.metrics}
    want = evaluate_trace(tr, cfg.control)
    path = want["path"]
    assert got[("control/recorded/path", "cross_track_rms_m")] == pytest.approx(path["cross_track_rms_m"], rel=1e-6)
    assert got[("control/recorded/path", "completion_time_s")] == pytest.approx(path["completion_time_s"], abs=0.1)
    for side in ("left", "right"):
        # references recomputed along the recorded pose agree with the ones the simulation issued
        assert got[(f"control/recorded/{side}", "rms_error_mps")] == pytest.approx(want[side]["rms_error_mps"],
                                                                                   abs=0.01)
        assert got[(f"control/recorded/{side}", "max_abs_command_rpm")] == pytest.approx(
            want[side]["max_abs_command_rpm"], rel=1e-6)
        assert got[(f"control/recorded/{side}", "funnel_violations")] == 0
    assert result.extra["labels"]["recorded"] == "recorded (ground_truth)"
    assert not result.warnings


def test_replay_finds_the_slip_patches_of_the_paper_run(tmp_path) -> None:
    from mrnc_eval.commands.control_runs import replayed_run
    from mrnc_eval.data import Trajectory, Waypoints
    from mrnc_eval.io.writers import LogWriter

    cfg = Config()
    sc = paper_circle_scenario(cfg.control)
    tr = run_closed_loop(sc, cfg.control, cfg.robot, "pid", record_every=20)
    quat = np.c_[np.zeros((tr.t.size, 2)), np.sin(tr.yaw / 2), np.cos(tr.yaw / 2)]
    log = tmp_path / "circle.mcap"
    with LogWriter(log, fmt="mcap") as w:
        w.write_path("/plan", Waypoints(sc.waypoints_xy, frame_id="map"), tr.t[0])
        w.write_odometry("/ground_truth", Trajectory(tr.t, np.c_[tr.x, tr.y, np.zeros_like(tr.t)], quat))
        w.write_joint_state("/wheel_speeds", tr.t, ["left_wheel", "right_wheel"],
                            np.c_[tr.v_wheel_left, tr.v_wheel_right] / cfg.robot.wheel_radius_m)
    run = replayed_run(log, cfg)
    traces, warnings = run.traces, run.warnings
    rec = traces["recorded"]
    assert "no pump-command topic" in warnings[0]
    for side in ("left", "right"):
        truth = getattr(tr, f"slip_{side}") > 0
        found = getattr(rec, f"slip_{side}") > 0
        assert np.mean(truth == found) > 0.95, side  # the patches, up to the smoothing at their edges
        assert np.median(getattr(rec, f"slip_{side}")[truth & found]) == pytest.approx(
            np.median(getattr(tr, f"slip_{side}")[truth & found]), abs=0.03)
