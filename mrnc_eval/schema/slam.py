"""A slam result's names (written by commands/slam.py)."""

from __future__ import annotations

# series.npz: times are s since the log start; positions (N, 3) m in the map frame
EST_T = "est_t"  # sweep stamps of the smoothed trajectory
EST_XYZ = "est_xyz"  # smoothed trajectory (each sweep re-anchored to its final keyframe)
EST_ONLINE_XYZ = "est_online_xyz"  # each sweep's pose as estimated when it was processed
KF_XYZ = "kf_xyz"  # keyframes
REF_XYZ = "ref_xyz"  # ground truth at the matched stamps
EST_ALIGNED_XYZ = "est_aligned_xyz"  # smoothed, SE(3) aligned to the ground truth
EST_ONLINE_ALIGNED_XYZ = "est_online_aligned_xyz"
SMOOTHED, ONLINE = "ape", "ape_online"  # the two trajectories' APE series prefixes


def ape_t(trajectory: str = SMOOTHED) -> str:
    """Stamps (s since the log start) of the APE of SMOOTHED or ONLINE."""
    return f"{trajectory}_t"


def ape_err(trajectory: str = SMOOTHED) -> str:
    """APE (m) of SMOOTHED or ONLINE at ape_t."""
    return f"{trajectory}_err_m"


# result.json extra
METHOD = "method"  # lio | kiss-icp
DESKEW = "deskew"  # how the sweeps were deskewed (kiss-icp on throttled logs: not at all)
TIMING_MS = "timing_ms"  # stage -> {mean, p95, max} ms per processed sweep
WALL_S = "wall_s"
LOG_DURATION_S = "log_duration_s"
FIRST_SWEEP_MS = "first_sweep_ms"
WARMUP_TOTAL_MS = "warmup_total_ms"
MAPPING_RATE = "mapping_rate"  # one line: sweeps mapped of decoded, Hz
ROLES = "roles"  # role -> topic of the log
GROUND_TRUTH = "ground_truth"  # the reference `table` reads back (a TUM file or log.mcap:/topic)
