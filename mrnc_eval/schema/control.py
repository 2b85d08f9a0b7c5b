"""A control result's names (written by commands/control.py)."""

from __future__ import annotations

# series.npz, per controller (or "recorded" for a replay) and side
V_REF, V_MEAS, U_RPM = "v_ref", "v_meas", "u_rpm"  # wheel-speed reference and measured (m/s), command (RPM)
U_FB_RPM, PHI_HAT = "u_fb_rpm", "phi_hat"  # feedback part of the command; RAID's adaptive parameter


def side_series(controller: str, side: str, quantity: str) -> str:
    """One side's ("left" or "right", control.closed_loop.SIDES) V_REF, V_MEAS, U_RPM, U_FB_RPM or PHI_HAT."""
    return f"{controller}_{side}_{quantity}"


def time(controller: str) -> str:
    """The controller's time base (s since the run's start)."""
    return f"{controller}_t"


def driven_xy(controller: str) -> str:
    """(N, 2) driven path, m (absent when the log has no pose)."""
    return f"{controller}_xy"


def cte(controller: str) -> str:
    """Cross-track error, m (path following only)."""
    return f"{controller}_cte_m"


def funnel(controller: str) -> str:
    """The funnel half-width o(t), m/s, on the controller's time base."""
    return f"{controller}_funnel_o"


def sweep_violation_rate(controller: str) -> str:
    """Robustness sweep: fraction of runs with a funnel violation per gain-mismatch bin."""
    return f"sweep_{controller}_violation_rate"


T = "t"  # the longest run's time base (s)
BODE_W = "bode_w_rad_s"  # frequencies of the loop responses, rad/s


def bode_magnitude(law: str) -> str:
    """|L(jw)| of the law's linear loop on the nominal plant, dB, at BODE_W."""
    return f"bode_{law}_mag_db"


def bode_phase(law: str) -> str:
    """arg L(jw), deg (unwrapped), at BODE_W."""
    return f"bode_{law}_phase_deg"


PATH_XY = "path_xy"  # (N, 2) planned path, m
FUNNEL_O = "funnel_o"  # o(t) on T
SWEEP_GAIN_MISMATCH_MID = "sweep_gain_mismatch_mid"  # bin centres of the sweep's gain mismatch

# result.json extra
MODE = "mode"  # replay | simulate | sweep
CONTROLLERS = "controllers"
LABELS = "labels"  # controller -> label
RUNS = "runs"  # sweep: plants per controller
REPLAY = "replay"  # path | wheel_speed
T0_STAMP_S = "t0_stamp_s"  # log time of the series' t = 0, s
DEFINITIONS = "definitions"
SATURATION_APPLIES_TO = "saturation_applies_to"
CURVATURE = "curvature"
ROLES = "roles"
