"""Per-side wheel-speed controllers behind one step interface.

Every law adds its feedback to the shared feed-forward f = 3000 v_ref RPM (control.model; `ff` is
that feed-forward alone, the negative control); the safety clamp
+/-u_max bounds the total command (default) or only the feedback part (paper-notes 4.3).
The compiled `controller_step` dispatches on a law id so the closed-loop engine stays one
compiled loop; the classes below wrap it for Python callers (replay, tests), one per law:
`step(t, v_ref, vdot_ref, v_meas, dt) -> (pump command RPM, ok)`. Errors: RAID uses
e = v - v_ref (paper), the baselines r - y. Stand-ins are labelled as such everywhere.
"""

from __future__ import annotations

import math

import numpy as np

from mrnc_eval.control.apc import (
    APC_AR_DELTA,
    APC_AR_THETA_MAX,
    APC_EPS,
    APC_ETA,
    APC_LAM,
    APC_MU,
    APC_N_PRED,
    APC_PERIOD,
    APC_PHI1,
    APC_RHO,
    APC_UNIT,
    apc_params,
    mfapc_step,
)
from mrnc_eval.control.config import ControlConfig
from mrnc_eval.control.foptc import (
    FOPTC_ANTI_WINDUP,
    FOPTC_C_H,
    FOPTC_FREEZE,
    FOPTC_HORIZON,
    FOPTC_K0,
    FOPTC_K_HAT,
    FOPTC_KI,
    FOPTC_TAU_HAT,
    foptc_params,
    foptc_step,
)
from mrnc_eval.control.jit_cache import FloatArray, kernel, pack_slots
from mrnc_eval.control.pid import PID_KD, PID_KI, PID_KP, PID_MODE, PID_TT, pid_params, pid_step
from mrnc_eval.control.raid import (
    RAID_BETA,
    RAID_E_UNIT,
    RAID_GAMMA,
    RAID_KAPPA,
    RAID_PHI0,
    RAID_SCALE,
    funnel,
    raid_params,
    raid_step,
    rbf_centres,
)

CONTROLLERS = ("raid", "pid", "apc", "foptc", "ff")
PAPER_ORDER = ("raid", "apc", "pid", "foptc")  # column order of the paper's Table II
FEEDBACK_LAWS = ("raid", "pid", "apc", "foptc")  # every law but the negative control
LABELS = {
    "raid": "RAID",
    "pid": "PID",
    "apc": "APC (stand-in: CFDL-MFAPC)",
    "foptc": "FOPTC (stand-in: prescribed-time gain)",
    "ff": "FF only (negative control)",
}
CONTROLLER_ID = {name: k for k, name in enumerate(CONTROLLERS)}
FF_ID = CONTROLLER_ID["ff"]


def _no_params(cfg: ControlConfig) -> list[float]:
    return []


_PARAMS = {"raid": raid_params, "pid": pid_params, "apc": apc_params, "foptc": foptc_params, "ff": _no_params}

# common parameter vector head, then the law's own parameters from P_LAW on
(P_FF, P_UMAX, P_SATFB, P_STEP, P_ANCHOR, P_OOV, P_OB, P_OSTAR, P_DETECTOR, P_RAMP_RATE, P_RESTART_STEP,
 P_SUPERVISE, P_RATE_FF) = range(13)
P_LAW = 13

# per-side state: the law's own slots [0, LAW_SLOTS), then the shared bookkeeping
LAW_SLOTS = 12
(S_SEG_START, S_LAST_REF, S_HELD, S_NEXT_UPDATE, S_INIT, S_RAMP_FROM, S_MOVING, S_RAMP_COUNTED, S_RESTARTS,
 S_PREV_U, S_STOP_E_OVER_O) = range(LAW_SLOTS, LAW_SLOTS + 11)
STATE_SIZE = LAW_SLOTS + 11

# status of one control period (controller_step): running, or the cause of a safety stop
OK, STOP_BARRIER, STOP_NON_FINITE, STOP_BARRIER_CLAMPED = range(4)
STOP_CAUSES = {STOP_BARRIER: "barrier", STOP_NON_FINITE: "non_finite", STOP_BARRIER_CLAMPED: "barrier_at_clamp"}
SUPERVISORS = ("raid_only", "all")  # control.supervisor.stop_rule


def controller_params(name: str, cfg: ControlConfig) -> FloatArray:
    """Pack the configuration of one law into a float vector for the compiled kernels."""
    if name not in _PARAMS:
        raise ValueError(f"unknown controller {name!r}; choose from {', '.join(CONTROLLERS)}")
    a, f = cfg.actuator, cfg.funnel
    common = pack_slots({P_FF: cfg.model.feedforward_rpm_per_mps, P_UMAX: a.u_max_rpm,
                         P_SATFB: 1.0 if a.saturation_applies_to == "feedback" else 0.0,
                         P_STEP: cfg.metrics.step_threshold_mps,
                         P_ANCHOR: 1.0 if f.anchor == "reference_change" else 0.0,
                         P_OOV: f.o_ov_mps, P_OB: f.o_b_mps, P_OSTAR: f.o_star_per_s,
                         P_DETECTOR: 1.0 if cfg.steps.detector == "ramp" else 0.0,
                         P_RAMP_RATE: cfg.steps.ramp_rate_mps2, P_RESTART_STEP: cfg.steps.restart_step_mps,
                         P_SUPERVISE: float(SUPERVISORS.index(cfg.supervisor.stop_rule)),
                         P_RATE_FF: cfg.kinematics.rate_feedforward_tau_s
                         if cfg.kinematics.reference_shaping == "slew_rate_ff" else 0.0})
    return np.asarray(common + _PARAMS[name](cfg), dtype=np.float64)


@kernel
def funnel_at(state: FloatArray, p: FloatArray, t: float) -> tuple[float, float]:
    """o(t), do/dt of this side's funnel, anchored at run start or at the last reference step."""
    t0 = state[S_SEG_START] if p[P_ANCHOR] > 0.5 else 0.0
    return funnel(t - t0, p[P_OOV], p[P_OB], p[P_OSTAR])


@kernel
def detect_step(state: FloatArray, p: FloatArray, t: float, v_ref: float, dt: float) -> None:
    """Restart this side's segment clock (funnel anchor, FOPTC's prescribed-time clock) on a step.
    ramp detector: the reference moves while |dr/dt| > ramp_rate (or jumps by more than the step
    threshold); once a movement has changed it by restart_step since it began, the clock restarts and
    is held at zero until the movement ends (t = 0 is the end of the ramp). per_sample (the old rule):
    restart where one sample changes it by more than the step threshold, which a slewed reference never
    does. Counts restarts (state[S_RESTARTS]); the first call starts the clock."""
    if state[S_INIT] == 0.0:
        state[S_SEG_START], state[S_RAMP_FROM], state[S_MOVING] = t, v_ref, 0.0
        return
    dr = v_ref - state[S_LAST_REF]
    if p[P_DETECTOR] < 0.5:
        if abs(dr) > p[P_STEP]:
            state[S_SEG_START] = t
            state[S_RESTARTS] += 1.0
        return
    if abs(dr) > p[P_STEP] or abs(dr) > p[P_RAMP_RATE] * dt:
        if state[S_MOVING] == 0.0:
            state[S_MOVING], state[S_RAMP_FROM], state[S_RAMP_COUNTED] = 1.0, state[S_LAST_REF], 0.0
        if abs(v_ref - state[S_RAMP_FROM]) >= p[P_RESTART_STEP]:
            state[S_SEG_START] = t
            if state[S_RAMP_COUNTED] == 0.0:
                state[S_RAMP_COUNTED] = 1.0
                state[S_RESTARTS] += 1.0
    else:
        state[S_MOVING] = 0.0


@kernel
def _stop(state: FloatArray, e: float, o: float, u_max: float) -> int:
    """Cause of a barrier stop: at the clamp when the previous command was saturated (no authority left)."""
    state[S_STOP_E_OVER_O] = abs(e) / o if o > 0.0 else np.inf
    return STOP_BARRIER_CLAMPED if abs(state[S_PREV_U]) >= u_max - 1e-9 else STOP_BARRIER


@kernel
def _baseline_feedback(cid: int, state: FloatArray, p: FloatArray, t: float, v_ref: float, v_meas: float, u_ff: float,
                       u_max: float, dt: float) -> float:
    """Feedback (RPM) of the baselines and the negative control for one period."""
    q = P_LAW
    if cid == 1:
        return pid_step(state, p[q + PID_KP], p[q + PID_KI], p[q + PID_KD], int(p[q + PID_MODE]), p[q + PID_TT],
                        v_ref - v_meas, u_ff, -u_max, u_max, dt)
    if cid == FF_ID:  # negative control: the shared feed-forward alone
        return 0.0
    if cid == 2:
        if t >= state[S_NEXT_UPDATE] - 1e-12:  # slow rate, held in between
            state[S_HELD] = mfapc_step(state, p[q + APC_PHI1], p[q + APC_ETA], p[q + APC_MU], p[q + APC_RHO],
                                       p[q + APC_LAM], p[q + APC_EPS], p[q + APC_UNIT], p[q + APC_N_PRED],
                                       p[q + APC_AR_DELTA], p[q + APC_AR_THETA_MAX], v_ref, v_meas, u_ff, -u_max, u_max)
            state[S_NEXT_UPDATE] = t + p[q + APC_PERIOD]
        held: float = state[S_HELD]
        return held
    return foptc_step(state, p[q + FOPTC_K0], p[q + FOPTC_C_H], p[q + FOPTC_HORIZON], p[q + FOPTC_FREEZE],
                      p[q + FOPTC_KI], p[q + FOPTC_TAU_HAT], p[q + FOPTC_K_HAT], p[q + FOPTC_ANTI_WINDUP] > 0.5,
                      t - state[S_SEG_START], v_ref - v_meas, u_ff, -u_max, u_max, dt)


@kernel
def controller_step(cid: int, state: FloatArray, p: FloatArray, centres: FloatArray, t: float, v_ref: float,
                    vdot_ref: float, v_meas: float, dt: float) -> tuple[float, int]:
    """One control period of law `cid` for one side: (pump command RPM after the clamp, status).
    status OK, or the cause of a safety stop (the command is then 0): RAID's barrier or a non-finite
    value, and with the supervisor on every law (control.supervisor.stop_rule = all) |e| >= o(t)."""
    u_ff = p[P_FF] * (v_ref + p[P_RATE_FF] * vdot_ref)  # rate term: slew_rate_ff shaping only
    u_max = p[P_UMAX]
    detect_step(state, p, t, v_ref, dt)
    if state[S_INIT] == 0.0:
        if cid == 0:
            state[0] = p[P_LAW + RAID_PHI0]  # phi(0)
        state[S_INIT] = 1.0
    state[S_LAST_REF] = v_ref
    q = P_LAW
    every_law = p[P_SUPERVISE] > 0.5  # SUPERVISORS[1]: the stop rule applies to every law
    o, odot = funnel_at(state, p, t)
    e = v_meas - v_ref
    if not math.isfinite(v_meas):
        return 0.0, STOP_NON_FINITE
    if every_law and cid != 0 and abs(e) >= o:  # the same stop rule for every law
        return 0.0, _stop(state, e, o, u_max)
    if cid == 0:
        u_fb, ok = raid_step(state, centres, p[q + RAID_GAMMA], p[q + RAID_BETA], p[q + RAID_KAPPA],
                             p[q + RAID_SCALE], e, o, odot, vdot_ref, v_meas, dt, p[q + RAID_E_UNIT])
        if not ok:  # the paper's stop rule: at the barrier, or a value became non-finite
            return 0.0, _stop(state, e, o, u_max) if abs(e) >= o else STOP_NON_FINITE
    else:
        u_fb = _baseline_feedback(cid, state, p, t, v_ref, v_meas, u_ff, u_max, dt)
    if not math.isfinite(u_fb):
        return 0.0, STOP_NON_FINITE
    # the safety clamp on the feedback part only, or on the total command (default)
    u = u_ff + min(max(u_fb, -u_max), u_max) if p[P_SATFB] > 0.5 else min(max(u_ff + u_fb, -u_max), u_max)
    state[S_PREV_U] = u
    return u, OK


class WheelController:
    """One side, one law: `step(t, v_ref, vdot_ref, v_meas, dt) -> (pump command RPM, ok)`."""

    name = ""

    def __init__(self, cfg: ControlConfig) -> None:
        self.label = LABELS[self.name]
        self.params = controller_params(self.name, cfg)
        self.centres = rbf_centres(cfg)
        self.state = np.zeros(STATE_SIZE)

    def step(self, t: float, v_ref: float, vdot_ref: float, v_meas: float, dt: float) -> tuple[float, bool]:
        u, status = controller_step(CONTROLLER_ID[self.name], self.state, self.params, self.centres,
                                    t, v_ref, vdot_ref, v_meas, dt)
        return u, status == OK

    @property
    def restarts(self) -> int:
        """Segment restarts so far (steps the detector found)."""
        return int(self.state[S_RESTARTS])

    def funnel(self, t: float) -> float:
        """o(t) in m/s as this controller anchors it."""
        return funnel_at(self.state, self.params, t)[0]


class RaidController(WheelController):
    """The paper's RAID law (config: control.raid, control.funnel)."""

    name = "raid"


class PidController(WheelController):
    """PID with anti-windup (config: control.pid)."""

    name = "pid"


class ApcController(WheelController):
    """APC stand-in: CFDL-MFAPC at 10 Hz with hold (config: control.apc)."""

    name = "apc"


class FoptcController(WheelController):
    """FOPTC stand-in: prescribed-time gain restarted per step (config: control.foptc)."""

    name = "foptc"


class FeedForwardOnly(WheelController):
    """Negative control: f = 3000 v_ref and no feedback. A test that credits a law with keeping the
    funnel or removing the error must fail for this one under the default plant."""

    name = "ff"


CONTROLLER_CLASSES: dict[str, type[WheelController]] = {
    c.name: c for c in (RaidController, PidController, ApcController, FoptcController, FeedForwardOnly)}


def make_controller(name: str, cfg: ControlConfig) -> WheelController:
    if name not in CONTROLLER_CLASSES:
        raise ValueError(f"unknown controller {name!r}; choose from {', '.join(CONTROLLERS)}")
    return CONTROLLER_CLASSES[name](cfg)
