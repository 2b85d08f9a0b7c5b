"""Slow (issue 16 item 5): a 40 s open-field drive at about 1 m/s with only 1-3 lone structures
(trees, poles, a parked machine, a container) within 30 m most of the time. Run:
    .venv/bin/python -m pytest -m slow tests/slam/test_slam_open_field_slow.py -s

The same log replayed with LIO-SAM's rules (the negative control) drifts much further: with few
edges it keeps the IMU guess, rough-ground normals and far, nearly collinear map neighbours pose
as yaw information that the degeneracy test trusts, graph #2 forgets the measured z, roll and
pitch on every degenerate sweep, and the initial attitude averages the start-up acceleration
into a tilted map. Without the wheels the LiDAR alone does not reach the issue's 0.15 m
(docs/simulation.md, "Open field", says why); the GNSS track (slam.gps.track, on without wheels,
not a LIO-SAM rule) now carries x, y on the fixes: 0.076 m with the ideal profile's, 0.84 m with the
field receiver's. With the wheel odometry (slam.wheel_odom, on by default), its yaw hold
an anchored first keyframe and scan-to-map turning about the base, the field profile comes to
0.025 m and the ideal one to 0.007 m; the same replay without the wheels, with the wheels but none
of the three, and with the wheels turning about the sensor are the negative controls.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from mrnc_eval.config import Config, replace_paths

pytestmark = pytest.mark.slow

# docs/simulation.md, "Open field": the drive and the LiDAR packets of the issue-16 log
DRIVE = {"sim.path_size_m": 40.0, "control.pure_pursuit.desired_speed_mps": 1.0,
         "control.pure_pursuit.max_speed_mps": 1.0, "control.pure_pursuit.speed_cap": False,
         "control.actuator.u_max_rpm": 4000.0, "sim.lidar.packet_profile": "RNG15_RFL8_NIR8",
         # the issue-16 log's wheels: the plant's speeds (the field profile's calibrated-realistic wheel
         # errors came later, issue 28: tests/slam/test_wheels_gnss_slow.py)
         "sim.wheels.model": "exact"}
LIO_SAM_RULES = {"slam.matching.match_without_edges": False, "slam.matching.ground_normal_min_z": 0.0,
                 "slam.matching.plane_min_spread_m": 0.0, "slam.features.ground_max_angle_deg": 0.0,
                 "slam.matching.max_rotation_correction_deg": 0.0, "slam.imu.degenerate_prior": "all",
                 "slam.imu.attitude_lookahead_s": 0.5, "slam.loop.min_eigenvalue": 0.0,
                 "slam.wheel_odom.enabled": False,
                 # LIO-SAM has no GNSS track (slam/gnss_track.py): without it x, y are IMU dead reckoning
                 "slam.gps.track": "never"}
NO_WHEELS = {"slam.wheel_odom.enabled": False}
# (profile, LiDAR): online APE limit, m. Ideal: ~2x the measured 0.076 m (0.44-0.65 m before the GNSS
# track; LIO-SAM's rules 5.9-7.6 m). Field: ~2x the measured 0.84 m (the GNSS track carrying x, y on the
# field receiver's fixes; 10.1-10.9 m of IMU drift before it, when the limit was 14 m); LIO-SAM's rules,
# which have no track, 18-53 m. With the track and LIO-SAM's other rules: 0.92 m.
CASES = {("field", "os0-32"): 1.7, ("ideal", "os0-64"): 0.15}


def _open_field_log(folder: Path, profile: str, lidar: str) -> Path:
    from mrnc_eval.recording.recorder import SimRequest, simulate_log

    return simulate_log(folder / f"open_field_{profile}_{lidar}.mcap", replace_paths(Config(), DRIVE),
                        SimRequest(scene="open_field", path="line", duration_s=40.0, lidar=lidar, columns=512,
                                   seed=2, profile=profile))


def _metrics(log: Path, out: Path, rules: dict[str, object]) -> dict[str, float]:
    from mrnc_eval.commands.slam import run_log

    r = run_log(log, replace_paths(Config(), rules), out, method="lio")
    return {m.name: float(m.value) for m in r.metrics if isinstance(m.value, (int, float))}


@pytest.mark.parametrize(("profile", "lidar"), list(CASES))
def test_open_field_drive_stays_within_the_limit_and_lio_sam_rules_do_not(profile: str, lidar: str,
                                                                          tmp_path: Path) -> None:
    log = _open_field_log(tmp_path, profile, lidar)
    ours = _metrics(log, tmp_path / "ours", NO_WHEELS)
    lio_sam = _metrics(log, tmp_path / "lio_sam", LIO_SAM_RULES)
    limit = CASES[(profile, lidar)]
    _print(f"{profile} profile, {lidar} x 512", {"this replay, no wheels": ours, "LIO-SAM rules": lio_sam})
    assert ours["ape_span_s"] > 35.0
    assert ours["ape_online_rmse_m"] < limit
    assert lio_sam["ape_online_rmse_m"] > limit  # the negative control fails the same test


# (profile, LiDAR): online APE limit with the wheel odometry (defaults), m, ~2x the measured 0.025 m
# (field, OS0-32: the field receiver claims 2 cm while its fixes wander 0.9 m RMS; 0.158 m before the
# GNSS gate bounded the claim by the fixes' scatter, 2026-11-26) and 0.007 m (ideal, OS0-64). Negative
# controls, all above the limits (measured 2026-11-26): without the wheels 11.6 m and 0.400 m; the
# wheels as at the start of this work (BEFORE: no yaw hold, LIO-SAM's free first keyframe, turning
# about the sensor) 0.139 m and 0.059 m; the wheels with the yaw hold and the anchor but turning
# about the sensor (SENSOR_PIVOT) 0.112 m and 0.053 m.
WHEEL_CASES = {("field", "os0-32"): 0.05, ("ideal", "os0-64"): 0.015}
SENSOR_PIVOT = {"slam.wheel_odom.pivot_max_gap_s": 0.0}
BEFORE = {**SENSOR_PIVOT, "slam.wheel_odom.yaw_information": 0.0, "slam.graph.anchor_start": "never"}


@pytest.mark.parametrize(("profile", "lidar"), list(WHEEL_CASES))
def test_open_field_with_wheel_odometry_stays_within_the_limit_and_without_does_not(profile: str, lidar: str,
                                                                                     tmp_path: Path) -> None:
    log = _open_field_log(tmp_path, profile, lidar)
    wheels = _metrics(log, tmp_path / "wheels", {})
    none = _metrics(log, tmp_path / "none", NO_WHEELS)
    before = _metrics(log, tmp_path / "before", BEFORE)
    sensor = _metrics(log, tmp_path / "sensor", SENSOR_PIVOT)
    limit = WHEEL_CASES[(profile, lidar)]
    _print(f"{profile} profile, {lidar} x 512",
           {"with wheel odometry": wheels, "without": none, "wheels, no yaw hold, free start, sensor pivot": before,
            "wheels, turning about the sensor": sensor})
    assert wheels["ape_span_s"] > 35.0
    assert wheels["ape_online_rmse_m"] < limit
    assert none["ape_online_rmse_m"] > limit  # the negative controls fail the same test
    assert before["ape_online_rmse_m"] > limit
    assert sensor["ape_online_rmse_m"] > limit


def _print(title: str, runs: dict[str, dict[str, float]]) -> None:
    print(f"\nopen field 40 s, {title}, APE online / smoothed / end drift online (m):")
    for name, v in runs.items():
        print(f"  {name}: {v['ape_online_rmse_m']:.3f} / {v['ape_rmse_m']:.3f} / {v['end_drift_online_m']:.3f}")
