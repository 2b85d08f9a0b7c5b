"""Slow (issue 28): the open line of the claims matrix (field profile, OS0-32 x 512, 40 s, float
GNSS) with the combined wheel errors (scale 2 %, L/R 2 %, effective track 1.6x, 0.05 m/s speed
noise), seed 3 (a report seed, never tuned on). Run:
    .venv/bin/python -m pytest -m slow tests/slam/test_wheels_gnss_slow.py -s

Held at about 2x what benchmarks/wheel_gnss_matrix.py measured (docs/simulation.md, "Wheels and
GNSS as a real machine has them"); the negative control is the same log with the online wheel
calibration off and LIO-SAM's GNSS gate (what main did before): it must fail the same limits.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.config import Config, replace_paths
from tests.slam.open_line import COMBINED_WHEELS, STOPPING_LOOP, simulate_open_line, simulate_open_loop

pytestmark = pytest.mark.slow

BEFORE = {"slam.wheel_odom.calibration.enabled": False, "slam.gps.gate": "lio_sam"}
# measured by benchmarks/wheel_gnss_matrix.py (46fc1c5), seed 3, combined + float: online APE 0.312 m, end drift
# 1.45 m (this test: the same); limits ~2x. Before (calibration off, LIO-SAM's gate): 0.547 m, 5.84 m drift
APE_LIMIT_M, DRIFT_LIMIT_M = 0.6, 3.0


@pytest.fixture(scope="module")
def combined_line(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate_open_line(tmp_path_factory.mktemp("wheels") / "line_combined_float_s3.mcap", seed=3,
                              wheels=COMBINED_WHEELS)


def _run(log: Path, out: Path, rules: dict[str, object], start_s: float | None = None) -> tuple[dict[str, float], dict]:
    from mrnc_eval.commands.slam import SweepWindow, run_log

    window = None if start_s is None else SweepWindow(start_s=start_s)
    r = run_log(log, replace_paths(Config(), rules), out, method="lio", window=window)
    metrics = {m.name: float(m.value) for m in r.metrics if isinstance(m.value, (int, float))}
    return metrics, r.extra.get("wheel_health", {})


def test_combined_wheel_errors_with_float_gnss(combined_line: Path, tmp_path: Path) -> None:
    truth = json.loads(combined_line.with_name("line_combined_float_s3.errors.json").read_text())["wheels"]
    m, health = _run(combined_line, tmp_path / "new", {})
    print(f"combined + float: online APE {m['ape_online_rmse_m']:.3f} m, end drift {m['end_drift_online_m']:.2f} m,"
          f" wheel_health {health}")
    assert m["ape_online_rmse_m"] < APE_LIMIT_M
    assert m["end_drift_online_m"] < DRIFT_LIMIT_M
    assert health["verdict"] != "ok"
    # a line has few turns: the track factor is only as good as its sigma says
    assert abs(health["track_factor"] - truth["track_factor"] * (1 + truth["scale_error"])) \
        < max(0.08, 3 * health["track_factor_sigma"])
    assert health["lr_mismatch"] == pytest.approx(truth["lr_mismatch"], abs=max(0.005, 3 * health["lr_mismatch_sigma"]))

    before, _ = _run(combined_line, tmp_path / "before", BEFORE)
    print(f"before (no calibration, LIO-SAM's GNSS gate): {before['ape_online_rmse_m']:.3f} m, "
          f"{before['end_drift_online_m']:.2f} m")
    assert before["ape_online_rmse_m"] > APE_LIMIT_M or before["end_drift_online_m"] > DRIFT_LIMIT_M


# No wheel odometry on the same open line (calibrated-wheel log, wheels off), float GNSS, seed 4 (a report
# seed): the GNSS track (slam.gps.track) against IMU dead reckoning along the degenerate directions.
# Measured (benchmarks/wheel_gnss_matrix.py): 0.473 m online APE with slam.gps.track_model=hypotheses (eighth
# session); 0.689 m with the step filter (track_model=steps) since
# slam.gps.track_both_axes (seventh session; 1.12 m before it, the fourth session's label gnss-prov; 1.50 m
# before the provisional alignment); 18.7 m with slam.gps.track=never (59.1 m before the per-feature
# re-query: dead reckoning is chaotic, single seeds move by ~0.4 m on rounding); limit ~2x the step filter's.
NO_WHEELS = {"slam.wheel_odom.enabled": False}
TRACK_LIMIT_M = 1.0  # 2.1x the bank's 0.473 m; the step filter read 0.689 m here


@pytest.fixture(scope="module")
def calibrated_line(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate_open_line(tmp_path_factory.mktemp("track") / "line_calibrated_float_s4.mcap", seed=4)


def _holds_and_its_control_fails(log: Path, out: Path, control: dict[str, object], limit_m: float) -> None:
    """Without wheels, float GNSS: the defaults' online APE under limit_m, and the negative control's
    (the defaults with `control` set) over it."""
    m, _ = _run(log, out / "default", NO_WHEELS)
    print(f"no wheels, float GNSS, {log.stem}: online APE {m['ape_online_rmse_m']:.3f} m, "
          f"end drift {m['end_drift_online_m']:.2f} m")
    assert m["ape_online_rmse_m"] < limit_m
    c, _ = _run(log, out / "control", {**NO_WHEELS, **control})
    print(f"no wheels, float GNSS, {log.stem}, {control}: online APE {c['ape_online_rmse_m']:.3f} m")
    assert c["ape_online_rmse_m"] > limit_m


def test_without_wheels_the_gnss_track_holds_the_open_line(calibrated_line: Path, tmp_path: Path) -> None:
    # negative control: no track, dead reckoning along the degenerate directions
    _holds_and_its_control_fails(calibrated_line, tmp_path, {"slam.gps.track": "never"}, TRACK_LIMIT_M)


# The must-show "no wheels + float GNSS: online APE < 1.0 m", report seed 5: the bank of multipath
# hypotheses (slam.gps.track_model=hypotheses, eighth session) 0.521 m (benchmarks/wheel_gnss_matrix.py;
# under 1.0 m in every perturbed setting tried); the step filter before it 1.064 m: the negative control.
BANK_LIMIT_M = 1.0


@pytest.fixture(scope="module")
def calibrated_line_s5(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate_open_line(tmp_path_factory.mktemp("bank") / "line_calibrated_float_s5.mcap", seed=5)


def test_without_wheels_multipath_hypotheses_hold_the_line_under_1_m(calibrated_line_s5: Path, tmp_path: Path) -> None:
    # negative control: the step filter the bank replaced
    _holds_and_its_control_fails(calibrated_line_s5, tmp_path, {"slam.gps.track_model": "steps"}, BANK_LIMIT_M)


# The rotation gate's z walk (docs/simulation.md, "Eighth session: the rotation gate's z walk"), report RTK
# seed 3 without wheels: from 18.6 s the gate turned down matches for their yaw, the guess's tilt drifted and
# z walked 1.7 m down (online APE 0.554 m). Kept tilt and z (slam.matching.max_tilt_correction_deg): 0.372 m.
# The z error (online z less the truth's, both from their first pose) is what the test holds. Tenth session:
# graph #2 started from the standing start's gyro bias, the heading no longer drifts here and the gate does not
# turn matches down (z error 0.104 m kept, 0.088 m whole): both runs leave the standing start off
# (slam.imu.standing_start_min_s=0) to meet the drifting heading the rule is for. Eleventh session: the first
# keyframe's roll and pitch held to 0.01 rad keep the tilt too (z error 0.162 m either way, no match turned down):
# both runs take LIO-SAM's 0.1 rad prior, where the rule is what keeps it. Fourteenth session: whether the 2 deg
# gate locks out on this log depends on the machine (the eleventh session's: 0.178 / 0.979 m; a 2-core machine
# of the fourteenth: 7 single rejections of 2.1-3.5 deg, never two in a row, so the rule never acted and both
# runs read 0.160 m to the bit): both runs take a 1 deg gate, which locked out on both seeds tried there (seed 3:
# 0.138 m kept, 6.69 m whole; seed 4: 0.123 / 3.00 m), and the test asserts the rule acted.
Z_WALK_LIMIT_M = 0.3  # the z error's RMS: 0.138 m with the tilt kept (2.2x), 6.69 m with the whole match rejected
LIOSAM_TILT_PRIOR = {"slam.graph.prior_variances": (1e-2, 1e-2, 3.141592653589793 ** 2, 1e8, 1e8, 1e8)}
DRIFTING_HEADING = {**NO_WHEELS, "slam.imu.standing_start_min_s": 0.0, **LIOSAM_TILT_PRIOR,
                    "slam.matching.max_rotation_correction_deg": 1.0}


@pytest.fixture(scope="module")
def rtk_line_s3(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate_open_line(tmp_path_factory.mktemp("zwalk") / "line_calibrated_rtk_s3.mcap", seed=3,
                              wheels={"sim.gnss.mode": "rtk"})


def _z_error_rms(log: Path, out: Path) -> float:
    from mrnc_eval.io.trajectory_files import read_tum

    online = read_tum(next(out.rglob("trajectory_online.tum")))
    truth = read_tum(log.with_suffix(".gt.tum"))
    i = np.clip(np.searchsorted(truth.stamps, online.stamps), 0, truth.stamps.size - 1)
    err = (online.positions[:, 2] - online.positions[0, 2]) - (truth.positions[i, 2] - truth.positions[i[0], 2])
    return float(np.sqrt(np.mean(err ** 2)))


def test_without_wheels_the_rotation_gate_keeps_the_tilt_and_z_does_not_walk(rtk_line_s3: Path,
                                                                              tmp_path: Path) -> None:
    m, _ = _run(rtk_line_s3, tmp_path / "tilt", DRIFTING_HEADING)
    z = _z_error_rms(rtk_line_s3, tmp_path / "tilt")
    print(f"no wheels, RTK, seed 3, tilt kept: online APE {m['ape_online_rmse_m']:.3f} m, z error RMS {z:.3f} m")
    assert z < Z_WALK_LIMIT_M
    events = json.loads(next((tmp_path / "tilt").rglob("result.json")).read_text())["events"]
    assert any("kept its roll, pitch and z" in e["message"] for e in events)  # the rule acted (36 sweeps measured)
    whole, _ = _run(rtk_line_s3, tmp_path / "whole", {**DRIFTING_HEADING, "slam.matching.max_tilt_correction_deg": 0.0})
    z_whole = _z_error_rms(rtk_line_s3, tmp_path / "whole")
    print(f"no wheels, RTK, seed 3, whole match rejected: online APE {whole['ape_online_rmse_m']:.3f} m, "
          f"z error RMS {z_whole:.3f} m")
    assert z_whole > Z_WALK_LIMIT_M  # negative control: the z walk


# The open loop without wheels, float GNSS, report seed 4 (ninth session, docs/simulation.md "the track's
# alignment on a turning stretch"): the loop turns 2-3 m after it starts, so the track's alignment, which
# waited for a stretch within 30 deg of heading, never came and the chain dead-reckoned: 39.7 m online APE.
# Aligned pair by pair on the turn: 0.714 m (benchmarks/wheel_gnss_matrix.py). Negative control: no track
# (slam.gps.track=never), what the loop had before. Tenth session: the loop driven at 0.7 m/s (at 1 m/s
# RAID stopped the machine after 13 m) with graph #2 started from the standing start's gyro bias: 0.674 m.
LOOP_LIMIT_M = 1.5


@pytest.fixture(scope="module")
def calibrated_loop_s4(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate_open_loop(tmp_path_factory.mktemp("loop") / "loop_calibrated_float_s4.mcap", seed=4)


def test_without_wheels_the_track_holds_the_open_loop(calibrated_loop_s4: Path, tmp_path: Path) -> None:
    _holds_and_its_control_fails(calibrated_loop_s4, tmp_path, {"slam.gps.track": "never"}, LOOP_LIMIT_M)


# The standing start's gyro bias (slam.imu.standing_start_min_s, tenth session), the open loop without wheels,
# float, report seed 5: the field IMU's turn-on yaw bias (-0.0155 rad/s) turned the heading 16 deg in the
# first 12 s, the track's alignment never passed its spread check and the chain dead-reckoned (21.4 m);
# graph #2 started from the 0.3 s standing start's bias: 0.640 m. Negative control: the standing start off.
START_BIAS_LIMIT_M = 1.3


@pytest.fixture(scope="module")
def calibrated_loop_s5(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate_open_loop(tmp_path_factory.mktemp("loop5") / "loop_calibrated_float_s5.mcap", seed=5)


def test_without_wheels_the_standing_start_holds_the_heading(calibrated_loop_s5: Path, tmp_path: Path) -> None:
    _holds_and_its_control_fails(calibrated_loop_s5, tmp_path, {"slam.imu.standing_start_min_s": 0.0},
                                 START_BIAS_LIMIT_M)


# Single-point fixes (sim.gnss.mode=single, 1.5 m) without wheels, open line, seed 40 (ninth session): LIO-SAM's
# gps_cov_threshold_m2 (2 m^2) dropped every fix and the chain dead-reckoned (15.4 m online APE); the track now
# takes them (slam.gps.track_cov_threshold_m2): 1.31 m. Negative control: the track held to the 2 m^2 limit.
SINGLE_LIMIT_M = 2.6


@pytest.fixture(scope="module")
def single_point_line(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate_open_line(tmp_path_factory.mktemp("single") / "line_calibrated_single_s40.mcap", seed=40,
                              wheels={"sim.gnss.mode": "single"})


def test_without_wheels_single_point_fixes_hold_the_line(single_point_line: Path, tmp_path: Path) -> None:
    _holds_and_its_control_fails(single_point_line, tmp_path, {"slam.gps.track_cov_threshold_m2": 2.0},
                                 SINGLE_LIMIT_M)


# The open line begun at 5 s without wheels, float, report seed 3 (ninth session): the first tilt from the 0.1 s
# look-ahead read the bumps (45.4 m online APE); the 2 s steady mean instead (imu.bumpy_start_attitude): 0.997 m.
# Negative control: a 90 deg limit (the look-ahead always kept).
BUMPY_LIMIT_M = 2.0


@pytest.fixture(scope="module")
def calibrated_line_s3(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate_open_line(tmp_path_factory.mktemp("bumpy") / "line_calibrated_float_s3.mcap", seed=3)


def _begun_at_5_s_holds_and_its_control_fails(log: Path, out: Path, monkeypatch: pytest.MonkeyPatch,
                                              control: tuple[str, float], limit_m: float) -> None:
    """Without wheels, float GNSS, the log cut 5 s after its start: the defaults' online APE under limit_m,
    and with the imu module's constant `control` (name, value) set, over it."""
    from mrnc_eval.slam import imu

    m, _ = _run(log, out / "default", NO_WHEELS, start_s=5.0)
    print(f"no wheels, begun at 5 s, {log.stem}: online APE {m['ape_online_rmse_m']:.3f} m")
    assert m["ape_online_rmse_m"] < limit_m
    monkeypatch.setattr(imu, *control)
    c, _ = _run(log, out / "control", NO_WHEELS, start_s=5.0)
    assert c["ape_online_rmse_m"] > limit_m


def test_without_wheels_a_log_begun_mid_drive_starts_level(calibrated_line_s3: Path, tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    _begun_at_5_s_holds_and_its_control_fails(calibrated_line_s3, tmp_path, monkeypatch, ("BUMPY_START_DEG", 90.0),
                                              BUMPY_LIMIT_M)


# The open loop begun at 5 s without wheels, float, report seed 3: the look-ahead's tilt 3.4 deg off, under the
# bumps' 5 deg, and the run failed (44.1 m); the gyro shows the machine turning, not starting up, so 1 deg is
# enough for the steady mean (imu.MOVING_START_DEG): 0.769 m, first tilt 0.24 deg off. Negative control: the
# bumps' 5 deg for a moving start too. The loop at 1 m/s (STOPPING_LOOP: it stops after 13 m and stands): the
# rule needs the gyro's standing spread from a stationary stretch; the 0.7 m/s loop begun at 5 s has none and
# the rule stays out (seeds 0-5: 0.40-1.16 m either way, tenth session).
MOVING_LIMIT_M = 1.6


@pytest.fixture(scope="module")
def calibrated_loop_s3(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate_open_loop(tmp_path_factory.mktemp("moving") / "loop_calibrated_float_s3.mcap", seed=3,
                              sets=STOPPING_LOOP)


def test_without_wheels_a_loop_begun_turning_starts_level(calibrated_loop_s3: Path, tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    from mrnc_eval.slam import imu

    _begun_at_5_s_holds_and_its_control_fails(calibrated_loop_s3, tmp_path, monkeypatch,
                                              ("MOVING_START_DEG", imu.BUMPY_START_DEG), MOVING_LIMIT_M)
