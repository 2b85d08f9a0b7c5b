"""Closed-loop simulation of the whole chain: pure pursuit -> inverse kinematics ->
per-side controller -> hydraulic drive with slip -> skid-steer body. Compiled (numba):
the wheel loop runs at 1 kHz, pure pursuit at its own rate (50 Hz by default)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from mrnc_eval.config import RobotConfig
from mrnc_eval.control.config import ControlConfig
from mrnc_eval.control.controllers import (
    CONTROLLER_ID,
    LABELS,
    STATE_SIZE,
    controller_params,
    controller_step,
    funnel_at,
)
from mrnc_eval.control.kinematics import inverse_kinematics, slew
from mrnc_eval.control.plant import body_step, drive_step, patches_array, slip_at
from mrnc_eval.control.pure_pursuit import pp_step
from mrnc_eval.control.raid import rbf_centres
from mrnc_eval.control.scenario import Scenario, waypoint_scenario

N_OUT = 18  # recorded channels, see ClosedLoopTrace


@dataclass
class ClosedLoopTrace:
    controller: str
    label: str
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    v: np.ndarray  # true body speed, m/s
    omega: np.ndarray  # true yaw rate, rad/s
    cmd_v: np.ndarray
    cmd_omega: np.ndarray
    v_ref_left: np.ndarray
    v_ref_right: np.ndarray
    v_wheel_left: np.ndarray  # measured (encoder) wheel surface speed, m/s
    v_wheel_right: np.ndarray
    slip_left: np.ndarray
    slip_right: np.ndarray
    u_left: np.ndarray  # pump command after the safety clamp, RPM
    u_right: np.ndarray
    funnel: np.ndarray  # o(t) of the left side, m/s (equal to the right's unless anchored per step)
    events: list[dict] = field(default_factory=list)  # safety stops
    completed: bool = False
    completion_time_s: float = float("nan")  # when pure pursuit declared the goal reached
    waypoints: np.ndarray | None = None
    funnel_right: np.ndarray | None = None  # o(t) of the right side, m/s (None: same as `funnel`)

    def funnel_of(self, side: str) -> np.ndarray:
        return self.funnel_right if side == "right" and self.funnel_right is not None else self.funnel


@njit(cache=True)
def _simulate(cid, p, centres, wp, patches, x0, y0, yaw0, dt, n_steps, pp_every, pp_args, track, chi, gain, tau,
              delay_steps, dz, noise, accel_lim, deriv_tau, seed, record_every, linger_steps):
    np.random.seed(seed)
    n_rec = n_steps // record_every + 1
    out = np.zeros((n_rec, N_OUT))
    stops = np.full((2, 2), -1.0)  # per side: (time, cause 1=barrier/non-finite)
    state_l = np.zeros(STATE_SIZE)
    state_r = np.zeros(STATE_SIZE)
    buf_l = np.zeros(delay_steps + 1)
    buf_r = np.zeros(delay_steps + 1)
    a = math.exp(-dt / tau)
    x, y, yaw = x0, y0, yaw0
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
            cmd_v, cmd_w, idx, done, _, _ = pp_step(
                x, y, yaw, v_body, wp, idx, pp_args[0], pp_args[1], pp_args[2], pp_args[3], track,
                pp_args[4] > 0.5, pp_args[5] > 0.5, int(pp_args[6]), pp_args[7], pp_args[8], pp_args[9],
                pp_args[10] > 0.5, pp_args[11], pp_args[12], pp_args[13])
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
            u_l, ok = controller_step(cid, state_l, p, centres, t, ref_l, dref_l, meas_l, dt)
            if not ok:
                stopped_l = True
                stops[0, 0], stops[0, 1] = t, 1.0
        if not stopped_r:
            u_r, ok = controller_step(cid, state_r, p, centres, t, ref_r, dref_r, meas_r, dt)
            if not ok:
                stopped_r = True
                stops[1, 0], stops[1, 1] = t, 1.0
        # transport delay (ring buffer), dead band, lag, slip
        slot = k % (delay_steps + 1)
        ul_del, ur_del = buf_l[slot], buf_r[slot]
        buf_l[slot], buf_r[slot] = u_l, u_r
        cy, sy = math.cos(yaw), math.sin(yaw)
        s_l = slip_at(x - half * sy, y + half * cy, patches)
        s_r = slip_at(x + half * sy, y - half * cy, patches)
        vw_l = drive_step(vw_l, ul_del, s_l, gain, a, dz)
        vw_r = drive_step(vw_r, ur_del, s_r, gain, a, dz)
        x, y, yaw, v_body, w_body = body_step(x, y, yaw, (1.0 - s_l) * vw_l, (1.0 - s_r) * vw_r, track * chi, dt)
        if k % record_every == 0:
            o_l, _ = funnel_at(state_l, p, t)
            o_r, _ = funnel_at(state_r, p, t)
            row = out[k_rec]
            row[0], row[1], row[2], row[3], row[4], row[5] = t, x, y, yaw, v_body, w_body
            row[6], row[7], row[8], row[9] = cmd_v, cmd_w, ref_l, ref_r
            row[10], row[11], row[12], row[13] = meas_l, meas_r, s_l, s_r
            row[14], row[15], row[16], row[17] = u_l, u_r, o_l, o_r
            k_rec += 1
        if done_at >= 0 and k - done_at >= linger_steps:
            break
    return out[:k_rec], stops, done, done_at


def run_closed_loop(scenario: Scenario | np.ndarray, cfg: ControlConfig, robot: RobotConfig, controller: str = "raid",
                    *, duration_s: float | None = None, seed: int | None = None,
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
    n_steps = int(round(duration_s / dt))
    pp_args = np.array([pp.lookahead_m, pp.desired_speed_mps, pp.max_speed_mps, robot.max_speed_mps,
                        1.0 if pp.curvature == "paper_literal" else 0.0, 1.0 if pp.speed_cap else 0.0,
                        float(pp.search_window), pp.goal_tolerance_m, pp.approach_distance_m,
                        pp.min_approach_speed_mps, 1.0 if pp.velocity_scaled_lookahead else 0.0,
                        pp.lookahead_time_s, pp.lookahead_min_m, pp.lookahead_max_m])
    pl = cfg.plant
    x0, y0, yaw0 = scenario.start_pose
    out, stops, done, done_at = _simulate(
        CONTROLLER_ID[controller], controller_params(controller, cfg), rbf_centres(cfg),
        np.ascontiguousarray(scenario.waypoints_xy, dtype=np.float64), patches_array(list(scenario.slip_patches)),
        x0, y0, yaw0, dt, n_steps, max(1, int(round(cfg.rate_hz / pp.rate_hz))), pp_args, robot.track_width_m,
        pl.icr_expansion, pl.gain_mps_per_rpm, pl.tau_s, int(round(pl.delay_s / dt)), pl.dead_band_rpm,
        pl.speed_noise_mps, cfg.kinematics.reference_accel_limit_mps2, cfg.kinematics.reference_derivative_tau_s,
        cfg.seed if seed is None else seed, max(1, int(record_every)), int(round(2.0 / dt)))
    cols = out.T
    events = [{"t_s": float(stops[i, 0]), "kind": "safety_stop", "side": side, "cause": "barrier_or_non_finite",
               "message": f"{side} side: |e| reached the funnel o(t) or a value became non-finite; command set to 0"}
              for i, side in enumerate(("left", "right")) if stops[i, 0] >= 0]
    return ClosedLoopTrace(controller, LABELS[controller], *cols[:17], events=events, completed=bool(done),
                           completion_time_s=done_at * dt if done else float("nan"),
                           waypoints=scenario.waypoints_xy, funnel_right=cols[17])
