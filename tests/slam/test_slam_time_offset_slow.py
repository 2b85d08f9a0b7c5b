"""Slow: LiDAR-IMU time offset on a 100 s simulated log with rocking (OS0-32 x 512 at 10 Hz, yard
circle on rough ground: terrain 0.5 m, roughness 5 cm; ideal sensor profile). Run:
    .venv/bin/python -m pytest -m slow tests/slam/test_slam_time_offset_slow.py -s

The IMU stamps are shifted in the test (the lag a late IMU clock would give). Measured on the
estimator that weights each axis by its own residual and slam.imu.noise_from_log (issue 28): lag 0
-> -1.69 ms (no health finding), 8 ms -> 5.53 ms, 30 ms -> 27.69 ms, standard error 0.75-0.82 ms;
8 ms with the known offset applied -> -1.69 ms (noise_from_log off: -1.76, 5.14, 27.66 ms). The
estimate sits about 2.5 ms below every lag, about 3 standard errors: the SLAM's poses on rocking
axes lag the truth by that much (against the ground truth, field yard logs: -1.5 to -4 ms on roll
and pitch), a bias of the LiDAR side, not of the estimator (on ground-truth rotations it reads
0.06 ms). Applying estimates during the run (slam.imu.refine_time_offset_s = 10) gives 5.31 ms at
8 ms and 28.13 ms at 30 ms: it takes out part of what the poses keep of a large lag from the IMU
(test_slam_time_offset_refine_slow.py), not this bias.
Before (equal axis weights): lag 0 -> -1.7 ms, 8 ms -> 5.5 ms.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from mrnc_eval.config import Config, replace_path

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def rocking_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from mrnc_eval.recording.recorder import SimRequest, simulate_log

    cfg = replace_path(replace_path(Config(), "sim.terrain_amplitude_m", 0.5), "sim.terrain_roughness_m", 0.05)
    return simulate_log(tmp_path_factory.mktemp("rock") / "rock100.mcap", cfg,
                        SimRequest(scene="yard", path="circle", duration_s=100.0, lidar="os0-32", columns=512,
                                   seed=4))


def _estimate(log: Path, lag_s: float, applied_s: float = 0.0) -> float:
    from mrnc_eval.io import open_log
    from mrnc_eval.slam.mapping_interval import MappingInterval
    from mrnc_eval.slam.replay import run_slam

    cfg = replace_path(Config(), "slam.imu.time_offset_s", applied_s)
    with open_log(log) as lg:
        imu = lg.imu()
        out = run_slam(lg.sweeps(keep=MappingInterval(interval_s=cfg.slam.mapping_interval_s).take),
                       replace(imu, stamps=imu.stamps + lag_s), cfg.slam,
                       sensor_to_imu=lg.transform("os_sensor", "os_imu"))
    assert out.imu_time_offset_s is not None
    return out.imu_time_offset_s


def test_8_and_30_ms_imu_lags_are_recovered_within_3_ms_and_a_known_lag_is_applied(rocking_log: Path) -> None:
    none = _estimate(rocking_log, 0.0)
    late = _estimate(rocking_log, 0.008)
    later = _estimate(rocking_log, 0.030)
    applied = _estimate(rocking_log, 0.008, applied_s=0.008)
    print(f"\nIMU time offset: lag 0 -> {none * 1e3:.2f} ms, lag 8 ms -> {late * 1e3:.2f} ms, lag 30 ms -> "
          f"{later * 1e3:.2f} ms, lag 8 ms with slam.imu.time_offset_s = 0.008 -> {applied * 1e3:.2f} ms")
    assert abs(none) < 0.002  # negative control: no health finding
    assert abs(late - 0.008) < 0.003  # not the 2 ms: see the module docstring
    assert abs(later - 0.030) < 0.003
    assert abs(applied - none) < 0.0005  # the known offset removes the lag before anything else
