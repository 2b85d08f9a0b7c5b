"""Slow: LiDAR-IMU time offset on a 100 s simulated log with rocking (OS0-32 x 512 at 10 Hz, yard
circle on rough ground: terrain 0.5 m, roughness 5 cm; ideal sensor profile). Run:
    .venv/bin/python -m pytest -m slow tests/slam/test_slam_time_offset_slow.py -s

The IMU stamps are shifted in the test (the lag a late IMU clock would give). Measured with the offset
read from the sweeps re-matched after the run (slam.imu.time_offset_from=rematch, the default;
slam/offset_rematch.py; each kept sweep's points capped at 2,000 edge and 2,000 surface): lag 0 ->
-1.16 ms, 8 ms -> 6.67 ms, 30 ms -> 28.66 ms, jackknife standard error 0.35-0.39 ms; 8 ms with the
known offset applied -> -1.16 ms (every point kept: -0.78 / 7.07 / 29.04 ms). The limit, 2 ms, is about
1.5x the worst error (1.34 ms). Negative control, the online poses (time_offset_from=online, the estimate before
the re-match): 8 ms -> 5.19 ms, 30 ms -> 27.55 ms (2.81 / 2.45 ms short: the poses keep part of the
IMU-driven guess). Before the re-match's estimate (online poses, per-axis weights, noise_from_log):
lag 0 -> -1.69 ms, 8 ms -> 5.53 ms, 30 ms -> 27.69 ms.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from mrnc_eval.config import Config, replace_path

pytestmark = pytest.mark.slow
LIMIT_S = 0.002  # the 2 ms: 1.5x the worst error measured with the re-match (1.34 ms)


@pytest.fixture(scope="module")
def rocking_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from mrnc_eval.recording.recorder import SimRequest, simulate_log

    cfg = replace_path(replace_path(Config(), "sim.terrain_amplitude_m", 0.5), "sim.terrain_roughness_m", 0.05)
    return simulate_log(tmp_path_factory.mktemp("rock") / "rock100.mcap", cfg,
                        SimRequest(scene="yard", path="circle", duration_s=100.0, lidar="os0-32", columns=512,
                                   seed=4))


def _estimate(log: Path, lag_s: float, applied_s: float = 0.0, source: str = "rematch") -> tuple[float, float]:
    """(estimate, standard error), s, with slam.imu.time_offset_from = `source`."""
    from mrnc_eval.io import open_log
    from mrnc_eval.slam.mapping_interval import MappingInterval
    from mrnc_eval.slam.replay import run_slam

    cfg = replace_path(replace_path(Config(), "slam.imu.time_offset_s", applied_s), "slam.imu.time_offset_from", source)
    with open_log(log) as lg:
        imu = lg.imu()
        out = run_slam(lg.sweeps(keep=MappingInterval(interval_s=cfg.slam.mapping_interval_s).take),
                       replace(imu, stamps=imu.stamps + lag_s), cfg.slam,
                       sensor_to_imu=lg.transform("os_sensor", "os_imu"))
    assert out.imu_time_offset_s is not None
    assert out.imu_time_offset_sigma_s is not None
    return out.imu_time_offset_s, out.imu_time_offset_sigma_s


def test_8_and_30_ms_imu_lags_are_read_within_2_ms_from_rematched_sweeps_and_a_known_lag_is_applied(
        rocking_log: Path) -> None:
    found = {lag: _estimate(rocking_log, lag) for lag in (0.0, 0.008, 0.030)}
    online = {lag: _estimate(rocking_log, lag, source="online")[0] for lag in (0.008, 0.030)}
    applied = _estimate(rocking_log, 0.008, applied_s=0.008)[0]
    print("\nIMU time offset, re-match: " + ", ".join(f"lag {lag * 1e3:.0f} ms -> {o * 1e3:.2f} +- {s * 1e3:.2f} ms"
                                                    for lag, (o, s) in found.items())
          + "; online poses: " + ", ".join(f"{lag * 1e3:.0f} ms -> {o * 1e3:.2f} ms" for lag, o in online.items())
          + f"; lag 8 ms with slam.imu.time_offset_s = 0.008 -> {applied * 1e3:.2f} ms")
    for lag, (offset, _) in found.items():
        assert abs(offset - lag) < LIMIT_S  # lag 0: no health finding
    # negative control: the online poses keep part of the IMU's lag and read it short
    assert max(abs(o - lag) for lag, o in online.items()) > LIMIT_S
    assert abs(applied - found[0.0][0]) < 0.0005  # the known offset removes the lag before anything else
