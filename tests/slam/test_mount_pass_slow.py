"""Slow (issue 28 must-show "open line, calibrated wheels + float GNSS: end drift < 0.5 m"): the field
profile's LiDAR sits at /tf_static's mount turned by roll 0.3, pitch -0.4, yaw 0.5 deg; the origin
alignment of the end drift turns the whole 40 m by the first base pose's pitch (0.4 deg is 0.28 m of z).
The mount check reads the pitch from the motion and slam.mount_check.apply runs the log again on the
corrected mount. Report seed 4 (never tuned on). Run:
    .venv/bin/python -m pytest -m slow tests/slam/test_mount_pass_slow.py -s
"""

from __future__ import annotations

from pathlib import Path

import pytest

from mrnc_eval.config import Config, replace_paths
from tests.slam.open_line import simulate_open_line

pytestmark = pytest.mark.slow

# measured (benchmarks/wheel_gnss_matrix.py, labels s11mc / s11mc0, eleventh session): end drift 0.394 m with
# the pass, 0.509 m without it; the end's z -0.093 / -0.320 m; the first pass reads pitch -0.33 +- 0.07 deg
DRIFT_LIMIT_M = 0.5  # the issue's
Z_LIMIT_M = 0.15  # the end's z with the pass; without it the mount's pitch puts 0.28 m there


@pytest.fixture(scope="module")
def line_s4(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate_open_line(tmp_path_factory.mktemp("mount") / "line_calibrated_float_s4.mcap", seed=4)


def _run(log: Path, out: Path, apply: bool) -> tuple[float, float, dict]:
    """(online end drift m, the end's z under the origin alignment m, the mount check record)."""
    from mrnc_eval.commands.slam import run_log
    from mrnc_eval.evaluation.ape import ape
    from mrnc_eval.io.trajectory_files import read_tum

    r = run_log(log, replace_paths(Config(), {"slam.mount_check.apply": apply}), out, method="lio")
    drift = r.metric("end_drift_online_m")
    assert drift is not None
    gt, online = read_tum(log.with_suffix(".gt.tum")), read_tum(out / "trajectory_online.tum")
    z = float(ape(gt, online, align="origin", max_diff=0.05).decompose().vertical_m[-1])
    return float(drift.value), z, r.extra["mount_check"]


def test_the_mount_pass_takes_the_line_s_end_drift_under_half_a_metre(line_s4: Path, tmp_path: Path) -> None:
    true_pitch = Config().sim.field.calibration.lidar_rpy_error_deg[1]
    drift, z, check = _run(line_s4, tmp_path / "on", apply=True)
    print(f"mount pass: end drift {drift:.3f} m, z {z:+.3f} m, first pass {check.get('first_pass')}")
    assert check["first_pass"]["pitch_deg"] == pytest.approx(true_pitch, abs=0.15)
    assert abs(check["pitch_deg"]) < 0.1
    assert drift < DRIFT_LIMIT_M
    assert abs(z) < Z_LIMIT_M
    # negative control: /tf_static's mount kept
    drift_off, z_off, _ = _run(line_s4, tmp_path / "off", apply=False)
    print(f"without: end drift {drift_off:.3f} m, z {z_off:+.3f} m")
    assert abs(z_off) > 2 * Z_LIMIT_M - 0.1  # measured 0.32 m
    assert drift_off > drift + 0.06  # measured 0.115 m apart
