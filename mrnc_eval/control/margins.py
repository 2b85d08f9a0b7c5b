"""Loop margins of the linear (or linearised) laws on one side's drive (issue 25 items 1, 8).

Plant (dead band and clamp left out: small-signal around a cruise point): P(s) = K e^{-s d} / (tau s + 1),
K in (m/s)/RPM, tau s, d s. Laws as transfer functions from speed error (m/s) to RPM:
PID kp + ki/s + kd s; FOPTC's frozen gain (tau_hat/K_hat) (g + ki/s) with g = k0 + c h / delta (and
g = k0 + c h / T right after a restart); RAID's interior gain (raid.interior_gain) as a P law. APC is
adaptive (no fixed linear law) and FF has no loop: no margins. Evaluated on a log-spaced grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrnc_eval.control.config import ControlConfig, DriveConfig
from mrnc_eval.control.jit_cache import FloatArray


@dataclass(frozen=True, kw_only=True)
class Margins:
    gain_margin: float  # ratio (inf: the phase never reaches -180 deg below the grid's top)
    phase_margin_deg: float  # inf: |L| < 1 everywhere (no gain crossover)
    delay_margin_s: float  # extra transport delay that makes the loop unstable
    crossover_rad_s: float  # gain crossover (NaN without one)


OMEGA = np.logspace(-3, 4, 40000)  # rad/s


def plant_response(drive: DriveConfig, w: FloatArray = OMEGA) -> FloatArray:
    s = 1j * w
    return np.asarray(drive.gain_mps_per_rpm * np.exp(-s * drive.delay_s) / (drive.tau_s * s + 1.0))


def pi_response(kp: float, ki: float, kd: float = 0.0, w: FloatArray = OMEGA) -> FloatArray:
    s = 1j * w
    return np.asarray(kp + ki / s + kd * s)


def margins(loop: FloatArray, w: FloatArray = OMEGA) -> Margins:
    """Gain, phase and delay margins of the open loop L(jw) sampled on w (rad/s)."""
    mag = np.abs(loop)
    phase = np.unwrap(np.angle(loop))
    cross = np.flatnonzero((mag[:-1] >= 1.0) & (mag[1:] < 1.0))
    if cross.size:
        k = int(cross[-1])
        wc = float(w[k])
        pm = float(np.degrees(np.pi + phase[k]))
        dm = float(np.radians(pm) / wc) if pm > 0 else 0.0
    else:
        wc, pm, dm = float("nan"), float("inf"), float("inf")
    p180 = np.flatnonzero((phase[:-1] > -np.pi) & (phase[1:] <= -np.pi))
    gm = float(1.0 / mag[int(p180[0])]) if p180.size else float("inf")
    return Margins(gain_margin=gm, phase_margin_deg=pm, delay_margin_s=dm, crossover_rad_s=wc)


def law_responses(cfg: ControlConfig, raid_gain_rpm_per_mps: float, w: FloatArray = OMEGA) -> dict[str, FloatArray]:
    """C(jw) (RPM per m/s) of every law with a fixed linear form; RAID's linearised interior gain given."""
    f = cfg.foptc
    scale = f.tau_hat_s / f.k_hat
    return {
        "raid": np.full(w.shape, raid_gain_rpm_per_mps, dtype=complex),
        "pid": pi_response(cfg.pid.kp, cfg.pid.ki, cfg.pid.kd, w),
        "foptc": pi_response(scale * (f.k0 + f.c_h / f.freeze_before_s), scale * f.ki, 0.0, w),
        "foptc_restart": pi_response(scale * (f.k0 + f.c_h / f.horizon_s), scale * f.ki, 0.0, w),
    }


def loop_margins(cfg: ControlConfig, raid_gain_rpm_per_mps: float,
                 drive: DriveConfig | None = None) -> dict[str, Margins]:
    """Margins of every linear law on `drive` (default: the plant's left side)."""
    p = plant_response(drive or cfg.plant.left)
    return {name: margins(c * p) for name, c in law_responses(cfg, raid_gain_rpm_per_mps).items()}


def critical_p_gain(drive: DriveConfig) -> float:
    """The proportional gain (RPM per m/s) at which a P law loses stability on `drive` (its gain margin at 1)."""
    return margins(plant_response(drive)).gain_margin


def loop_summary(cfg: ControlConfig, v_cruise: float) -> dict[str, object]:
    """RAID's declared output unit, its interior (linearised) gain at cruise and where its local gain
    reaches PID's k_p and the P-law stability limit, and the margins of every linear law on the
    left drive: what is printed beside Table II and stored in the result."""
    from mrnc_eval.control.raid import e_over_o_at_gain, interior_gain, output_units

    rpm_per_unit, e_unit = output_units(cfg)
    drive = cfg.plant.left
    gain = interior_gain(cfg, v=v_cruise, phi=0.0)
    k_crit = critical_p_gain(drive)
    return {
        "raid_output_unit": cfg.raid.output_unit,
        "raid_rpm_per_law_unit": rpm_per_unit,
        "raid_error_unit_mps": e_unit,
        "raid_interior_gain_rpm_per_mps": gain,
        "raid_interior_gain_phi0_rpm_per_mps": interior_gain(cfg, v=v_cruise, phi=cfg.raid.phi0),
        "raid_e_over_o_at_pid_kp": e_over_o_at_gain(cfg, cfg.pid.kp, v=v_cruise, phi=0.0),
        "raid_e_over_o_at_stability_limit": e_over_o_at_gain(cfg, k_crit, v=v_cruise, phi=0.0),
        "p_gain_stability_limit_rpm_per_mps": k_crit,
        "pid_kp_rpm_per_mps": cfg.pid.kp,
        "v_cruise_mps": v_cruise,
        "margins": {name: m.__dict__ for name, m in loop_margins(cfg, gain, drive).items()},
    }


def bode(cfg: ControlConfig, raid_gain_rpm_per_mps: float,
         points: int = 400) -> tuple[FloatArray, dict[str, FloatArray]]:
    """(w rad/s, {law: open loop L(jw) = C(jw) P(jw)}) on the left drive, `points` log-spaced frequencies."""
    w = np.logspace(-2, 3, points)
    p = plant_response(cfg.plant.left, w)
    return w, {name: c * p for name, c in law_responses(cfg, raid_gain_rpm_per_mps, w).items()}
