"""Closed-loop simulation of the whole chain: pure pursuit -> inverse kinematics ->
per-side controller -> hydraulic drive with slip -> skid-steer body. Compiled (numba):
the wheel loop runs at 1 kHz, pure pursuit at its own rate (50 Hz by default)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mrnc_eval.control.config import ControlConfig, RobotGeometry, reference_accel_limit
from mrnc_eval.control.controllers import (
    CONTROLLER_ID,
    LABELS,
    OK,
    P_ANCHOR,
    P_FF,
    P_RATE_FF,
    S_RESTARTS,
    S_STOP_E_OVER_O,
    STATE_SIZE,
    STOP_CAUSES,
    controller_params,
    controller_step,
    funnel_at,
)
from mrnc_eval.control.jit_cache import FloatArray, kernel
from mrnc_eval.control.kinematics import inverse_kinematics, slew
from mrnc_eval.control.plant import body_step_trig, drive_step, leaky_gain, patches_array, slip_at
from mrnc_eval.control.pure_pursuit import pp_step, pure_pursuit_params
from mrnc_eval.control.raid import rbf_centres
from mrnc_eval.control.scenario import Scenario, waypoint_scenario

# Recorded channels: the columns of the compiled loop's output, one ClosedLoopTrace field each.
(CH_T, CH_X, CH_Y, CH_YAW, CH_V, CH_OMEGA, CH_CMD_V, CH_CMD_OMEGA, CH_REF_L, CH_REF_R, CH_MEAS_L, CH_MEAS_R,
 CH_SLIP_L, CH_SLIP_R, CH_U_L, CH_U_R, CH_FUNNEL_L, CH_FUNNEL_R, CH_UFB_L, CH_UFB_R, CH_PHI_L, CH_PHI_R) = range(22)
N_OUT = 22

# Counted at the full control rate (not only on recorded samples), per side and up to a safety stop:
# samples with |e| >= o(t),
# samples with |U| at the limit, IAE (m), and (at the end) the restarts of the segment clock.
ST_FUNNEL, ST_SATURATED, ST_IAE, ST_RESTARTS = range(4)
N_STATS = 4

CONTROLLER_ID_RAID = CONTROLLER_ID["raid"]

# Plant parameter vector (per side where the drive may differ), see `plant_params`.
(PL_GAIN_L, PL_GAIN_R, PL_TAU_L, PL_TAU_R, PL_DELAY_L, PL_DELAY_R, PL_DZ_L, PL_DZ_R, PL_CHI, PL_NOISE,
 PL_TRACK, PL_LEAK_L, PL_LEAK_R, PL_U_MAX) = range(14)
PL_SIZE = 14

# Run settings of the compiled loop (counts stored as floats), see `run_closed_loop`.
(RUN_DT, RUN_STEPS, RUN_PP_EVERY, RUN_RECORD_EVERY, RUN_LINGER, RUN_X0, RUN_Y0, RUN_YAW0, RUN_ACCEL_LIMIT,
 RUN_DERIV_TAU, RUN_SEED, RUN_SAT_LEVEL) = range(12)
RUN_SIZE = 12


@dataclass(frozen=True, kw_only=True)
class SideTrace:
    """One side's channels of a trace (typed access instead of attribute names built from strings)."""

    v_ref: FloatArray  # reference wheel surface speed, m/s
    v_wheel: FloatArray  # measured wheel surface speed, m/s
    u: FloatArray  # pump command after the clamp, RPM
    slip: FloatArray  # slip ratio
    funnel: FloatArray  # o(t), m/s
    u_fb: FloatArray | None  # applied feedback U - f, RPM (None: unknown)
    phi: FloatArray | None  # RAID's phi-hat (None for the other laws)


SIDES = ("left", "right")


@dataclass
class ClosedLoopTrace:
    controller: str
    label: str
    t: FloatArray
    x: FloatArray
    y: FloatArray
    yaw: FloatArray
    v: FloatArray  # true body speed, m/s
    omega: FloatArray  # true yaw rate, rad/s
    cmd_v: FloatArray
    cmd_omega: FloatArray
    v_ref_left: FloatArray
    v_ref_right: FloatArray
    v_wheel_left: FloatArray  # measured (encoder) wheel surface speed, m/s
    v_wheel_right: FloatArray
    slip_left: FloatArray
    slip_right: FloatArray
    u_left: FloatArray  # pump command after the safety clamp, RPM
    u_right: FloatArray
    funnel: FloatArray  # o(t) of the left side, m/s (equal to the right's unless anchored per step)
    events: list[dict[str, Any]] = field(default_factory=list)  # safety stops
    completed: bool = False
    completion_time_s: float = float("nan")  # when pure pursuit declared the goal reached
    waypoints: FloatArray | None = None
    funnel_right: FloatArray | None = None  # o(t) of the right side, m/s (None: same as `funnel`)
    u_fb_left: FloatArray | None = None  # applied feedback U - f, RPM (None: unknown, e.g. a recording)
    u_fb_right: FloatArray | None = None
    phi_left: FloatArray | None = None  # RAID's adaptive parameter phi-hat (None for the other laws)
    phi_right: FloatArray | None = None
    full_rate_stats: FloatArray | None = None  # (2, N_STATS) left/right, counted every control period

    def funnel_of(self, side: str) -> FloatArray:
        return self.funnel_right if side == "right" and self.funnel_right is not None else self.funnel

    def side(self, side: str) -> SideTrace:
        """The channels of `side` ("left" or "right")."""
        if side == "left":
            return SideTrace(v_ref=self.v_ref_left, v_wheel=self.v_wheel_left, u=self.u_left, slip=self.slip_left,
                             funnel=self.funnel, u_fb=self.u_fb_left, phi=self.phi_left)
        if side == "right":
            return SideTrace(v_ref=self.v_ref_right, v_wheel=self.v_wheel_right, u=self.u_right, slip=self.slip_right,
                             funnel=self.funnel_of("right"), u_fb=self.u_fb_right, phi=self.phi_right)
        raise ValueError(f"side must be 'left' or 'right', not {side!r}")


def plant_params(cfg: ControlConfig, robot: RobotGeometry, dt: float) -> FloatArray:
    """Pack the drive and body model for the compiled loop (delays in whole periods of dt s)."""
    pl = cfg.plant
    p = np.zeros(PL_SIZE)
    p[PL_GAIN_L], p[PL_GAIN_R] = pl.left.gain_mps_per_rpm, pl.right.gain_mps_per_rpm
    p[PL_TAU_L], p[PL_TAU_R] = pl.left.tau_s, pl.right.tau_s
    p[PL_DELAY_L], p[PL_DELAY_R] = int(round(pl.left.delay_s / dt)), int(round(pl.right.delay_s / dt))
    p[PL_DZ_L], p[PL_DZ_R] = pl.left.dead_band_rpm, pl.right.dead_band_rpm
    p[PL_LEAK_L], p[PL_LEAK_R] = pl.left.leakage_at_limit, pl.right.leakage_at_limit
    p[PL_U_MAX] = cfg.actuator.u_max_rpm
    p[PL_CHI] = pl.icr_expansion
    p[PL_NOISE] = pl.speed_noise_mps
    p[PL_TRACK] = robot.track_width_m
    return p


@kernel
def _record(row: FloatArray, t: float, x: float, y: float, yaw: float, v_body: float, w_body: float,
            cmd_v: float, cmd_w: float, ref_l: float, ref_r: float, meas_l: float, meas_r: float,
            s_l: float, s_r: float, u_l: float, u_r: float, o_l: float, o_r: float, fb_l: float, fb_r: float,
            phi_l: float, phi_r: float) -> None:
    row[CH_T], row[CH_X], row[CH_Y], row[CH_YAW], row[CH_V], row[CH_OMEGA] = t, x, y, yaw, v_body, w_body
    row[CH_CMD_V], row[CH_CMD_OMEGA], row[CH_REF_L], row[CH_REF_R] = cmd_v, cmd_w, ref_l, ref_r
    row[CH_MEAS_L], row[CH_MEAS_R], row[CH_SLIP_L], row[CH_SLIP_R] = meas_l, meas_r, s_l, s_r
    row[CH_U_L], row[CH_U_R], row[CH_FUNNEL_L], row[CH_FUNNEL_R] = u_l, u_r, o_l, o_r
    row[CH_UFB_L], row[CH_UFB_R], row[CH_PHI_L], row[CH_PHI_R] = fb_l, fb_r, phi_l, phi_r


@kernel
def _count(stats: FloatArray, e: float, o: float, u: float, sat_level: float, dt: float) -> None:
    """Full-rate counters of one side: funnel violation, saturation, IAE."""
    if abs(e) >= o:
        stats[ST_FUNNEL] += 1.0
    if abs(u) >= sat_level:
        stats[ST_SATURATED] += 1.0
    stats[ST_IAE] += abs(e) * dt


@kernel
def _simulate(cid: int, p: FloatArray, centres: FloatArray, wp: FloatArray, patches: FloatArray,
              pp_params: FloatArray, plant: FloatArray,
              run: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, bool, int]:
    """The compiled loop (one function so numba keeps the whole chain in registers; split into
    kernels where a piece has its own meaning). Returns (recorded channels (n, N_OUT); safety stops
    per side (2, 3): time s, cause (controllers.STOP_CAUSES) and |e|/o at the stop, -1 when none; full-rate counters
    (2, N_STATS); done; step index of the goal or -1)."""
    dt = run[RUN_DT]
    n_steps, pp_every = int(run[RUN_STEPS]), int(run[RUN_PP_EVERY])
    record_every, linger_steps = int(run[RUN_RECORD_EVERY]), int(run[RUN_LINGER])
    accel_lim, deriv_tau = run[RUN_ACCEL_LIMIT], run[RUN_DERIV_TAU]
    np.random.seed(int(run[RUN_SEED]))
    track, noise = plant[PL_TRACK], plant[PL_NOISE]
    delay_l, delay_r = int(plant[PL_DELAY_L]), int(plant[PL_DELAY_R])
    n_rec = n_steps // record_every + 1
    out = np.zeros((n_rec, N_OUT))
    stops = np.full((2, 3), -1.0)
    stats = np.zeros((2, N_STATS))
    sat_level = run[RUN_SAT_LEVEL]
    u_ff_per_mps, rate_ff_s = p[P_FF], p[P_RATE_FF]
    raid = cid == CONTROLLER_ID_RAID
    per_step_funnel = p[P_ANCHOR] > 0.5
    state_l = np.zeros(STATE_SIZE)
    state_r = np.zeros(STATE_SIZE)
    buf_l = np.zeros(delay_l + 1)
    buf_r = np.zeros(delay_r + 1)
    a_l = math.exp(-dt / plant[PL_TAU_L])
    a_r = math.exp(-dt / plant[PL_TAU_R])
    x, y, yaw = run[RUN_X0], run[RUN_Y0], run[RUN_YAW0]
    cy, sy = math.cos(yaw), math.sin(yaw)
    v_body, w_body = 0.0, 0.0
    vw_l, vw_r = 0.0, 0.0
    ref_l, ref_r = 0.0, 0.0
    dref_l, dref_r = 0.0, 0.0
    cmd_v, cmd_w = 0.0, 0.0
    idx = 0
    done = False
    done_at = -1
    stopped_l, stopped_r = False, False
    k_rec = 0
    half = 0.5 * track
    for k in range(n_steps):
        t = k * dt
        if k % pp_every == 0 and not done:
            cmd_v, cmd_w, idx, done, _, _ = pp_step(x, y, yaw, v_body, wp, idx, pp_params)
            if done:
                cmd_v, cmd_w = 0.0, 0.0
                done_at = k
        tl, tr = inverse_kinematics(cmd_v, cmd_w, track)
        new_l = slew(ref_l, tl, accel_lim, dt)
        new_r = slew(ref_r, tr, accel_lim, dt)
        # first-order filtered derivative of the (piecewise) reference, 1/s
        beta = dt / (deriv_tau + dt)
        dref_l += beta * ((new_l - ref_l) / dt - dref_l)
        dref_r += beta * ((new_r - ref_r) / dt - dref_r)
        ref_l, ref_r = new_l, new_r
        meas_l = vw_l + noise * np.random.standard_normal()
        meas_r = vw_r + noise * np.random.standard_normal()
        u_l, u_r = 0.0, 0.0
        if not stopped_l:
            u_l, status = controller_step(cid, state_l, p, centres, t, ref_l, dref_l, meas_l, dt)
            if status != OK:
                stopped_l = True
                stops[0, 0], stops[0, 1], stops[0, 2] = t, status, state_l[S_STOP_E_OVER_O]
        if not stopped_r:
            u_r, status = controller_step(cid, state_r, p, centres, t, ref_r, dref_r, meas_r, dt)
            if status != OK:
                stopped_r = True
                stops[1, 0], stops[1, 1], stops[1, 2] = t, status, state_r[S_STOP_E_OVER_O]
        o_l, _ = funnel_at(state_l, p, t)
        o_r = funnel_at(state_r, p, t)[0] if per_step_funnel else o_l  # run-start anchoring: one o(t)
        # counted while the side runs: a stopped side's dead error is not tracking (time to stop is reported)
        if not stopped_l:
            _count(stats[0], meas_l - ref_l, o_l, u_l, sat_level, dt)
        if not stopped_r:
            _count(stats[1], meas_r - ref_r, o_r, u_r, sat_level, dt)
        # transport delay (ring buffers), dead band, lag, slip
        slot_l, slot_r = k % (delay_l + 1), k % (delay_r + 1)
        ul_del, ur_del = buf_l[slot_l], buf_r[slot_r]
        buf_l[slot_l], buf_r[slot_r] = u_l, u_r
        s_l = slip_at(x - half * sy, y + half * cy, patches)
        s_r = slip_at(x + half * sy, y - half * cy, patches)
        vw_l = drive_step(vw_l, ul_del, s_l, leaky_gain(plant[PL_GAIN_L], plant[PL_LEAK_L], ul_del, plant[PL_U_MAX]),
                          a_l, plant[PL_DZ_L])
        vw_r = drive_step(vw_r, ur_del, s_r, leaky_gain(plant[PL_GAIN_R], plant[PL_LEAK_R], ur_del, plant[PL_U_MAX]),
                          a_r, plant[PL_DZ_R])
        x, y, yaw, v_body, w_body, cy, sy = body_step_trig(x, y, yaw, cy, sy, (1.0 - s_l) * vw_l,
                                                           (1.0 - s_r) * vw_r, track * plant[PL_CHI], dt)
        if k % record_every == 0:
            # applied feedback: what the command holds beyond the feed-forward (0 after a safety stop)
            fb_l = u_l - u_ff_per_mps * (ref_l + rate_ff_s * dref_l) if not stopped_l else 0.0
            fb_r = u_r - u_ff_per_mps * (ref_r + rate_ff_s * dref_r) if not stopped_r else 0.0
            phi_l = state_l[0] if raid else math.nan
            phi_r = state_r[0] if raid else math.nan
            _record(out[k_rec], t, x, y, yaw, v_body, w_body, cmd_v, cmd_w, ref_l, ref_r, meas_l, meas_r,
                    s_l, s_r, u_l, u_r, o_l, o_r, fb_l, fb_r, phi_l, phi_r)
            k_rec += 1
        if done_at >= 0 and k - done_at >= linger_steps:
            break
    stats[0, ST_RESTARTS], stats[1, ST_RESTARTS] = state_l[S_RESTARTS], state_r[S_RESTARTS]
    return out[:k_rec], stops, stats, done, done_at


def run_closed_loop(scenario: Scenario | FloatArray, cfg: ControlConfig, robot: RobotGeometry,
                    controller: str = "raid", *, duration_s: float | None = None, seed: int | None = None,
                    record_every: int = 1) -> ClosedLoopTrace:
    """Drive `scenario` (or bare waypoints (N, 2) m, no slip) with `controller` at cfg.rate_hz
    until the path is done (plus 2 s) or `duration_s` has passed. Deterministic for a seed."""
    if controller not in CONTROLLER_ID:
        raise ValueError(f"unknown controller {controller!r}")
    if not isinstance(scenario, Scenario):
        scenario = waypoint_scenario(scenario)
    dt = 1.0 / cfg.rate_hz
    pp = cfg.pure_pursuit
    path_len = float(np.sum(np.linalg.norm(np.diff(scenario.waypoints_xy, axis=0), axis=1)))
    if duration_s is None:  # time to drive the path at a fraction of the desired speed, generous
        duration_s = 3.0 * path_len / max(pp.desired_speed_mps, 0.05) + 10.0
    run = np.zeros(RUN_SIZE)
    run[RUN_DT] = dt
    run[RUN_STEPS] = int(round(duration_s / dt))
    run[RUN_PP_EVERY] = max(1, int(round(cfg.rate_hz / pp.rate_hz)))
    run[RUN_RECORD_EVERY] = max(1, int(record_every))
    run[RUN_LINGER] = int(round(2.0 / dt))
    run[RUN_X0], run[RUN_Y0], run[RUN_YAW0] = scenario.start_pose
    run[RUN_ACCEL_LIMIT] = reference_accel_limit(cfg)
    run[RUN_DERIV_TAU] = cfg.kinematics.reference_derivative_tau_s
    run[RUN_SEED] = cfg.seed if seed is None else seed
    run[RUN_SAT_LEVEL] = cfg.actuator.u_max_rpm - cfg.metrics.saturation_tolerance_rpm
    out, stops, stats, done, done_at = _simulate(
        CONTROLLER_ID[controller], controller_params(controller, cfg), rbf_centres(cfg),
        np.ascontiguousarray(scenario.waypoints_xy, dtype=np.float64), patches_array(list(scenario.slip_patches)),
        pure_pursuit_params(pp, robot.track_width_m, robot.max_speed_mps), plant_params(cfg, robot, dt), run)
    return _trace(controller, out, stops, stats, bool(done), done_at * dt if done else float("nan"), scenario)


_STOP_TEXT = {"barrier": "|e| reached the funnel o(t)",
              "barrier_at_clamp": "|e| reached the funnel o(t) with the command at the clamp",
              "non_finite": "a value became non-finite"}


def _trace(controller: str, out: FloatArray, stops: FloatArray, stats: FloatArray, done: bool,
           completion_time_s: float, scenario: Scenario) -> ClosedLoopTrace:
    """The compiled loop's output as a trace, channel by channel."""
    events: list[dict[str, Any]] = [
        {"t_s": float(stops[i, 0]), "kind": "safety_stop", "side": side, "cause": STOP_CAUSES[int(stops[i, 1])],
         "e_over_o": float(stops[i, 2]),
         "message": f"{side} side: {_STOP_TEXT[STOP_CAUSES[int(stops[i, 1])]]}; command set to 0"}
        for i, side in enumerate(SIDES) if stops[i, 0] >= 0]
    c = out.T
    return ClosedLoopTrace(
        controller=controller, label=LABELS[controller], t=c[CH_T], x=c[CH_X], y=c[CH_Y], yaw=c[CH_YAW],
        v=c[CH_V], omega=c[CH_OMEGA], cmd_v=c[CH_CMD_V], cmd_omega=c[CH_CMD_OMEGA],
        v_ref_left=c[CH_REF_L], v_ref_right=c[CH_REF_R], v_wheel_left=c[CH_MEAS_L], v_wheel_right=c[CH_MEAS_R],
        slip_left=c[CH_SLIP_L], slip_right=c[CH_SLIP_R], u_left=c[CH_U_L], u_right=c[CH_U_R],
        funnel=c[CH_FUNNEL_L], funnel_right=c[CH_FUNNEL_R], events=events, completed=done,
        completion_time_s=completion_time_s, waypoints=scenario.waypoints_xy, u_fb_left=c[CH_UFB_L],
        u_fb_right=c[CH_UFB_R], phi_left=c[CH_PHI_L], phi_right=c[CH_PHI_R], full_rate_stats=stats)
