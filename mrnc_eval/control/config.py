"""Control-chain parameters (paper experiment section; resolutions in shared/docs/paper-notes.md).

Units are in the names or the help text. Where the paper is ambiguous the option is named
and its default documented; reports print the effective values.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Protocol

from mrnc_eval.params import param, section


class RobotGeometry(Protocol):
    """What the control chain needs to know about the machine (the config's robot section has it)."""

    @property
    def track_width_m(self) -> float:
        """Effective track Lr used by inverse kinematics, m."""
        ...

    @property
    def max_speed_mps(self) -> float:
        """Top forward speed of the machine, m/s (the pure pursuit speed cap)."""
        ...


@dataclass(frozen=True)
class PurePursuitConfig:
    """Path following by pure pursuit."""

    lookahead_m: float = param(1.0, "lookahead distance L (paper: 1 m)", "m")
    desired_speed_mps: float = param(0.38, "desired forward speed (paper: 0.38 m/s)", "m/s")
    max_speed_mps: float = param(0.4, "maximum speed setting (paper: 0.4 m/s); also bounds each side's "
                                 "reference (v and omega scaled together, curvature kept)", "m/s")
    curvature: Literal["standard", "paper_literal"] = param(
        "standard", "standard: kappa = 2 sin(alpha)/D (Coulter); paper_literal: delta = atan(2 L sin(alpha)/D), "
        "omega = v 2 tan(delta)/D as printed")
    speed_cap: bool = param(True, "apply the paper's cap v <= v_robot_max / (2 (1 + |tan(delta)| Lr / D)) "
                            "with v_robot_max = robot.max_speed_mps")
    search_window: int = param(3, "forward search window for the closest segment (segments); never backwards")
    goal_tolerance_m: float = param(0.25, "stop when the last waypoint is this close", "m")
    approach_distance_m: float = param(1.0, "slow down linearly inside this remaining distance", "m")
    min_approach_speed_mps: float = param(0.05, "speed floor while approaching the goal", "m/s")
    velocity_scaled_lookahead: bool = param(False, "L = clamp(|v| * lookahead_time_s, min, max)")
    lookahead_time_s: float = param(2.6, "lookahead time for the velocity-scaled lookahead", "s")
    lookahead_min_m: float = param(0.6, "minimum scaled lookahead", "m")
    lookahead_max_m: float = param(1.5, "maximum scaled lookahead", "m")
    rate_hz: float = param(50.0, "pure pursuit update rate (the wheel loop runs faster)", "Hz")


@dataclass(frozen=True)
class KinematicsConfig:
    """Inverse kinematics: how the wheel references are shaped."""

    reference_shaping: Literal["none", "slew", "slew_rate_ff"] = param(
        "slew", "wheel references: none (the inverse kinematics as issued, as the paper), slew (rate-limited by "
        "reference_accel_limit_mps2; not in the paper), slew_rate_ff (slewed, and every law's feed-forward adds "
        "f x rate_feedforward_tau_s x dv_ref/dt, the drive's lag during a ramp)")
    reference_accel_limit_mps2: float = param(
        0.3, "slew limit on each side's reference speed; keeps |e(0)| < o(0) at start-up (not in the paper)", "m/s^2")
    rate_feedforward_tau_s: float = param(0.4, "assumed drive lag of the rate feed-forward (slew_rate_ff)", "s",
                                          ge=0.0, le=10.0)
    reference_derivative_tau_s: float = param(0.05, "first-order filter on d(v_ref)/dt used by RAID", "s")


def reference_accel_limit(cfg: ControlConfig) -> float:
    """The slew limit in effect (m/s^2; 0 = none) under control.kinematics.reference_shaping."""
    k = cfg.kinematics
    return 0.0 if k.reference_shaping == "none" else k.reference_accel_limit_mps2


def shaping_text(cfg: ControlConfig) -> str:
    """The reference shaping in effect, for every report."""
    k = cfg.kinematics
    if k.reference_shaping == "none":
        return "reference shaping: none (inverse kinematics as issued)"
    text = f"reference shaping: slew {k.reference_accel_limit_mps2:g} m/s^2 (not in the paper)"
    if k.reference_shaping == "slew_rate_ff":
        text += f" with rate feed-forward (lag {k.rate_feedforward_tau_s:g} s)"
    return text


@dataclass(frozen=True)
class FunnelConfig:
    """The prescribed-performance funnel o(t) of the paper."""

    o_ov_mps: float = param(0.30, "funnel start o(0) = o_ov (paper: 0.19 + 0.11)", "m/s")
    o_b_mps: float = param(0.11, "funnel floor o_b (steady-state bound)", "m/s")
    o_star_per_s: float = param(0.09, "funnel decay rate o* (paper: 0.00009 per 1 kHz sample)", "1/s")
    anchor: Literal["run_start", "reference_change"] = param(
        "run_start", "where t = 0 of o(t) is: run start, or restarted at each reference change")


@dataclass(frozen=True)
class StepDetectorConfig:
    """When a side's segment clock restarts (the per-step funnel anchor, FOPTC's prescribed-time clock)."""

    detector: Literal["ramp", "per_sample"] = param(
        "ramp", "ramp: a movement of the reference (|dr/dt| > ramp_rate_mps2) that has changed it by "
        "restart_step_mps restarts the clock, held at zero until the ramp ends; per_sample: one sample must change "
        "it by more than control.metrics.step_threshold_mps (never fires under the reference slew; the old rule)")
    ramp_rate_mps2: float = param(0.05, "the reference is moving where |dr/dt| exceeds this", "m/s^2", gt=0.0)
    restart_step_mps: float = param(0.1, "a movement that changes the reference by this much is a step", "m/s",
                                    gt=0.0)


@dataclass(frozen=True)
class SupervisorConfig:
    """The safety stop: which laws it applies to."""

    stop_rule: Literal["raid_only", "all"] = param(
        "raid_only", "the paper's safety stop (|e| >= o(t) or a non-finite value: command 0 on that side for the "
        "rest of the run): for RAID alone (paper), or for every law (parity)")


@dataclass(frozen=True)
class RaidConfig:
    """The RAID controller of the paper (RBF network, adaptive law)."""

    beta: float = param(1.2, "beta (paper)", gt=0.0)
    kappa: float = param(5.2, "kappa of the adaptive law (paper)")
    n_neurons: int = param(9, "RBF neurons N (paper)")
    gamma: float = param(0.13, "RBF width gamma (paper)")
    centre_seed: int = param(7, "seed of the RBF centres alpha = 2 rand - 1 (recorded in reports)")
    phi0: float = param(0.5, "initial adaptive parameter phi(0) (phi = 0 is a fixed point, so non-zero)")
    feedback_scale_rpm: float = param(1.0, "scale of the RAID feedback in RPM per law unit (the paper states no "
                                      "unit; 1 = the literal reading)", "RPM")
    output_unit: Literal["rpm_per_unit", "error_over_floor", "feedforward_gain"] = param(
        "rpm_per_unit", "how the law's output becomes RPM (the paper's law is dimensionally inhomogeneous): "
        "rpm_per_unit = feedback_scale_rpm RPM per law unit with e in m/s; error_over_floor = e, o, do/dt divided "
        "by o_b first; feedforward_gain = the output read as m/s x the feed-forward gain (3000 RPM per m/s) x "
        "feedback_scale_rpm. Reported with the interior gain beside Table II")
    scale_study: tuple[float, ...] = param((1.0, 10.0, 100.0), "feedback scales RAID is also run at in "
                                           "control --mode simulate (the scale study table; empty: none)", "RPM",
                                           gt=0.0, interval=False)


@dataclass(frozen=True)
class PidConfig:
    """The PID baseline controller."""

    kp: float = param(4800.0, "proportional gain", "RPM/(m/s)")
    ki: float = param(12000.0, "integral gain", "RPM/m")
    kd: float = param(0.0, "derivative gain", "RPM s/(m/s)")
    anti_windup: Literal["back_calculation", "conditional", "none"] = param("back_calculation", "anti-windup scheme")
    tracking_time_s: float = param(0.3, "back-calculation tracking time T_t", "s")


@dataclass(frozen=True)
class ApcConfig:
    """Stand-in for the paper's APC: Hou's CFDL-MFAPC (source paper unavailable; control-reference 3)."""

    rate_hz: float = param(10.0, "update rate; the MFAPC increment is held between updates", "Hz")
    phi1: float = param(0.2, "initial pseudo partial derivative phi(1), (m/s) per normalised command unit")
    eta: float = param(0.5, "PPD estimator step eta")
    mu: float = param(1.0, "PPD estimator regulariser mu")
    rho: float = param(0.3, "control step rho")
    lam: float = param(1.0, "control move penalty lambda (<= 0.05 limit-cycles on the clamp when normalised)")
    eps: float = param(1e-5, "PPD reset threshold epsilon")
    n_pred: int = param(5, "prediction horizon N_p (the control horizon N_u is 2)")
    ar_delta: float = param(1.0, "regulariser delta of the AR(3) PPD predictor")
    ar_theta_max: float = param(10.0, "reset bound M of the AR(3) coefficients")
    rpm_per_unit: float = param(3000.0, "normalisation u_n = U / rpm_per_unit", "RPM")


@dataclass(frozen=True)
class FoptcConfig:
    """Stand-in for the paper's FOPTC: prescribed-time time-varying gain (Song et al. 2017), restarted per step."""

    k0: float = param(2.5, "base gain", "1/s")
    c_h: float = param(1.0, "c * h of the prescribed-time gain")
    horizon_s: float = param(1.0, "prescribed time T", "s")
    freeze_before_s: float = param(0.25, "gain frozen at T - delta", "s")
    ki: float = param(4.0, "integral gain", "1/s^2")
    tau_hat_s: float = param(0.4, "assumed drive time constant", "s")
    k_hat: float = param(1.0 / 3000.0, "assumed drive gain", "(m/s)/RPM")
    anti_windup: bool = param(True, "conditional integration against the actuator clamp (not in the source law)")


@dataclass(frozen=True)
class ActuatorConfig:
    """The pump actuators: the safety limit and what it bounds."""

    u_max_rpm: float = param(1250.0, "safety actuator limit |U*| (paper)", "RPM")
    saturation_applies_to: Literal["total", "feedback"] = param(
        "total", "whether 1250 RPM bounds the total pump command (default) or only the feedback part")


@dataclass(frozen=True)
class ControllerModelConfig:
    """What every controller assumes about the drive. The plant (control.plant) is a separate model
    and by default differs from this one, so feedback has something to correct."""

    feedforward_rpm_per_mps: float = param(
        3000.0, "feed-forward f = 3000 v_ref (paper): the controllers' model of the drive is K = 1/3000 "
        "(m/s)/RPM with no dead band", "RPM/(m/s)")


# Default plant: 10 % stronger than the controllers' model (K = 1.1/3000) plus a 60 RPM dead band that the
# feed-forward does not know. Why this one: at the paper's cruise the outer side runs at 0.40 m/s, and the
# feed-forward alone asks 1200 of the 1250 RPM. A weaker plant (1/3300, control-reference's toy plant) needs
# 0.40 * 3300 + 60 = 1380 RPM: unreachable, every controller would only show saturation. The stronger plant
# needs 0.40 * 2727 + 60 = 1151 RPM, leaving ~100 RPM of authority, and leaves the feed-forward alone with
# e = K (f - dz) - v = 0.1 v - 0.022 m/s, i.e. +0.018 m/s on the outer side: an error feedback must remove.
# The sweep (control.sweep) covers the weaker plants.
DEFAULT_GAIN_MPS_PER_RPM = 1.1 / 3000.0


@dataclass(frozen=True)
class DriveConfig:
    """One side's hydraulic in-wheel drive: u_eff = deadband(u(k - d)), v <- a v + (1 - a) K (1 - s) u_eff."""

    gain_mps_per_rpm: float = param(DEFAULT_GAIN_MPS_PER_RPM, "true drive gain K (controllers assume 1/3000)",
                                    "(m/s)/RPM")
    tau_s: float = param(0.4, "first-order lag of the hydraulic drive (estimate)", "s")
    delay_s: float = param(0.04, "transport delay", "s")
    dead_band_rpm: float = param(60.0, "pump dead band (unknown to the feed-forward)", "RPM")
    leakage_at_limit: float = param(
        0.0, "pressure-dependent leakage: the gain falls linearly with the delayed command, K_eff = K (1 - "
        "leakage_at_limit min(|u| / u_max, 1)); 0 = off (the default plant), 0.05 = 5 % less speed per RPM at "
        "the 1250 RPM limit")


@dataclass(frozen=True)
class PlantConfig:
    """The simulated machine (not what the controllers assume: see control.model)."""

    left: DriveConfig = section(DriveConfig, "left-side drive")
    right: DriveConfig = section(DriveConfig, "right-side drive")
    icr_expansion: float = param(1.0, "chi: body yaw rate uses Lr * chi as effective track (1 = same as IK)")
    speed_noise_mps: float = param(0.002, "white noise on measured wheel speed", "m/s")


@dataclass(frozen=True)
class SlipPatchConfig:
    """One patch of slippery ground in the scenario."""

    x_m: float = param(0.0, "patch centre x", "m")
    y_m: float = param(0.0, "patch centre y", "m")
    radius_m: float = param(1.0, "patch radius", "m")
    slip: float = param(0.15, "slip ratio on the patch (wet/soft ground 0.08-0.20)")


@dataclass(frozen=True)
class ScenarioConfig:
    """The paper's scenario: circle, waypoints, slip patches."""

    circle_radius_m: float = param(5.0, "paper scenario: circle radius", "m")
    n_waypoints: int = param(8, "paper scenario: waypoints on the circle")
    centre_xy_m: tuple[float, float] = param(
        (6.583, -6.0), "circle centre. The paper's GPS figure shows slip from (2,-8) to (2,-4) and at (7,-1); "
        "the 5 m circle through all three has its centre at (2 + sqrt(21), -6) = (6.583, -6)", "m")
    start_angle_deg: float = param(
        247.5, "polar angle of the start (and first waypoint) about the centre; waypoints follow clockwise every "
        "360/n degrees. 247.5 puts waypoints at 202.5 and 157.5 deg, i.e. at (2,-8) and (2,-4), and the robot "
        "reaches the first slip patch after ~10 s (paper: slip at about 10-20 s)", "deg")
    slip_patches: list[SlipPatchConfig] = param(
        [SlipPatchConfig(1.583, -6.0, 2.1, 0.15), SlipPatchConfig(7.0, -1.0, 1.2, 0.18)],
        "soft, wet ground patches: one over the arc (2,-8)..(2,-4), one at (7,-1) (paper's GPS figure)")


@dataclass(frozen=True)
class MetricsConfig:
    """How settling, steady state, saturation and recovery are measured."""

    settling_band: float = param(0.02, "settling band relative to |step|")
    settling_floor_mps: float = param(0.02, "absolute floor of the settling band", "m/s")
    step_threshold_mps: float = param(1e-3, "a per-sample reference change larger than this restarts a "
                                      "segment (controller state, funnel anchoring)", "m/s")
    ramp_rate_mps2: float = param(0.05, "the reference is ramping where |dr/dt| exceeds this", "m/s^2")
    min_step_mps: float = param(0.1, "a ramp (or jump) changing the reference by at least this is a step "
                                "for settling/overshoot; the clock starts where the ramp starts", "m/s")
    steady_state_statistic: Literal["mean_abs", "abs_mean"] = param(
        "mean_abs", "steady-state error over the end window: mean |r - y| (paper-notes 6) or |mean(r - y)| "
        "(a signed bias; measurement noise averages out)")
    steady_window_fraction: float = param(0.2, "steady-state window: this fraction of the segment ...")
    steady_window_max_s: float = param(2.0, "... but at most this long", "s")
    step_window_s: float = param(10.0, "a step is evaluated up to this long after its ramp ends (or up to the "
                                 "next step); later disturbances belong to recovery, not settling", "s")
    saturation_tolerance_rpm: float = param(1.0, "a command within this of the limit counts as saturated", "RPM")
    feedback_share_min_rpm: float = param(1.0, "feedback share |u_fb|/|U| is taken over samples with |U| above "
                                          "this (0/0 at standstill is not a share)", "RPM")
    recovery_band_mps: float = param(0.02, "recovered when |e| stays below this after a slip event", "m/s")
    recovery_hold_s: float = param(1.0, "... for at least this long", "s")
    recovery_horizon_s: float = param(15.0, "not recovered if it takes longer than this", "s")


@dataclass(frozen=True)
class PaperMetricsConfig:
    """Table II read the way the paper's numbers read (see evaluation.control_metrics.paper_metrics):
    the start-up step 0 -> cruise per side, settling into a band around the cruise speed, overshoot
    relative to the cruise speed, steady-state error over the steady cruise."""

    band: float = param(0.02, "settling band relative to the cruise speed")
    smoothing_s: float = param(0.05, "centred moving mean over the measured speed before all three metrics: the "
                               "2 mm/s white measurement noise would otherwise be read as overshoot (+4 sigma = "
                               "2 % of cruise over a few thousand samples); 50 ms divides it by ~7 at 1 kHz", "s")
    startup_window_s: float = param(
        8.0, "the start-up step is judged this long after the reference leaves zero (the paper circle's first "
        "slip patch starts at ~10 s; a disturbance is recovery, not settling)", "s")
    cruise_tolerance: float = param(0.05, "steady cruise: reference within this fraction of the cruise speed")
    cruise_fraction: float = param(0.9, "cruise speed = median reference where it is above this fraction of its "
                                   "maximum")


@dataclass(frozen=True)
class SweepConfig:
    """Robustness sweep (control --mode sweep): N plants drawn uniformly from these ranges; every
    controller runs on the same draws. Gain mismatch m sets K = (1 + m) / feed-forward gain on both sides."""

    runs: int = param(100, "plants drawn", ge=1, le=100_000)
    seed: int = param(0, "seed of the draws (also the measurement-noise seed of run k is seed + k)")
    gain_mismatch: tuple[float, float] = param((-0.3, 0.3), "relative drive-gain error range")
    dead_band_rpm: tuple[float, float] = param((30.0, 150.0), "dead band range", "RPM")
    delay_s: tuple[float, float] = param((0.02, 0.08), "transport delay range", "s")
    tau_s: tuple[float, float] = param((0.2, 0.8), "drive time constant range", "s")
    slip_scale: tuple[float, float] = param((0.0, 2.0), "slip severity: the scenario's patch slip ratios "
                                            "(0.15, 0.18) times this factor")
    duration_s: float = param(100.0, "simulated time per run (the paper circle takes ~98 s)", "s", gt=0.0, le=86_400.0)
    record_every: int = param(20, "record every n-th control period (20: 50 Hz, the pure pursuit rate) for the "
                              "per-run steady-state error and cross-track RMS; funnel violations, saturation and "
                              "IAE are counted at the full rate")
    saturation_limit: float = param(0.2, "a run 'saturates' when either side is saturated longer than this "
                                    "fraction of the time")
    workers: int = param(0, "worker processes (0: all cores)")


@dataclass(frozen=True)
class IdentifyConfig:
    """control --mode identify: the drive model of control.plant fitted to a log's commands and wheel speeds."""

    command_signal: Literal["held", "sampled"] = param(
        "held", "how the recorded pump command runs between its messages: held (what a pump does with its "
        "command messages) or sampled (a faster command recorded at a lower rate: linear between samples, as in "
        "the simulator's logs, whose 1 kHz commands are written at the wheel rate)")
    max_delay_s: float = param(0.2, "longest transport delay searched", "s", gt=0.0, le=10.0)
    sweep_sigmas: float = param(3.0, "the identified plant's sweep ranges: estimate +/- this many standard "
                                "deviations (at least 5 % of the estimate; delay at least 5 ms)", gt=0.0, le=100.0)


@dataclass(frozen=True)
class TuneConfig:
    """control --mode tune: every law's free parameters (control/tune.py SPACE) searched with the same
    optimiser, cost and budget on the nominal plant; reported on a different noise seed."""

    budget: int = param(64, "closed-loop runs per law (the configured gains count as the first)", ge=1, le=100_000)
    seed: int = param(0, "seed of the scrambled Halton search points (the same for every law)", ge=0)
    noise_seed_offset: int = param(1, "tuning runs use measurement-noise seed control.seed + this; the table "
                                   "reports on control.seed (tune on some seeds, report on others)", ge=1)
    duration_s: float = param(100.0, "simulated time per tuning run (the paper circle takes ~98 s)", "s", gt=0.0,
                              le=86_400.0)
    stop_penalty_m: float = param(5.0, "cost added per side with a safety stop (IAE units)", "m", ge=0.0)
    violation_penalty_m: float = param(1.0, "cost added per side that left the funnel while running", "m", ge=0.0)


@dataclass(frozen=True)
class ControlConfig:
    """Pure pursuit, kinematics, the controllers, the plant and the control metrics."""

    rate_hz: float = param(1000.0, "wheel control loop rate of the closed-loop simulation", "Hz")
    seed: int = param(0, "seed of the measurement noise")
    pure_pursuit: PurePursuitConfig = section(PurePursuitConfig, "path following")
    kinematics: KinematicsConfig = section(KinematicsConfig, "inverse kinematics and reference shaping")
    funnel: FunnelConfig = section(FunnelConfig, "RAID prescribed-performance funnel o(t)")
    steps: StepDetectorConfig = section(StepDetectorConfig, "step detector: restarts of the per-step clocks")
    supervisor: SupervisorConfig = section(SupervisorConfig, "safety stop on funnel exit")
    raid: RaidConfig = section(RaidConfig, "RAID controller (paper)")
    pid: PidConfig = section(PidConfig, "PID baseline")
    apc: ApcConfig = section(ApcConfig, "APC baseline (stand-in: CFDL-MFAPC)")
    foptc: FoptcConfig = section(FoptcConfig, "FOPTC baseline (stand-in: prescribed-time gain)")
    actuator: ActuatorConfig = section(ActuatorConfig, "pump command limits")
    model: ControllerModelConfig = section(ControllerModelConfig, "what the controllers assume (feed-forward)")
    plant: PlantConfig = section(PlantConfig, "the simulated hydraulic in-wheel drives (differs from control.model)")
    scenario: ScenarioConfig = section(ScenarioConfig, "the paper's circle experiment")
    metrics: MetricsConfig = section(MetricsConfig, "Table II metric definitions (segments: any log)")
    paper_metrics: PaperMetricsConfig = section(PaperMetricsConfig, "Table II as the paper reads it (simulate)")
    sweep: SweepConfig = section(SweepConfig, "robustness sweep over plants")
    identify: IdentifyConfig = section(IdentifyConfig, "drive identification from a log (control --mode identify)")
    tune: TuneConfig = section(TuneConfig, "equal-effort tuning (control --mode tune)")
