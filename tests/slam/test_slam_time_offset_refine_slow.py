"""Slow: applying the IMU-LiDAR offset during the run (slam.imu.refine_time_offset_s) on a 40 s
field-profile yard log (OS0-32 x 512, seed 3, standing 3 s, ideal wheels, field GNSS) whose IMU is
30 ms late (the field's 5 ms + 25 ms shifted in the test). Run:
    .venv/bin/python -m pytest -m slow tests/slam/test_slam_time_offset_refine_slow.py -s

One estimate after the run reads only part of a large lag, since the poses keep part of the IMU-driven
guess; applied every 10 s, the poses that follow keep less of it. Measured (main 8bad290, after the
per-feature re-query): 26.06 ms once after the run, 28.74 ms applied every 10 s (before the re-query:
23.56 / 27.38 ms). The limit is ~2x the refined error; the negative control (one estimate) must fail
that same limit.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from mrnc_eval.config import Config, replace_path

pytestmark = pytest.mark.slow
TRUE_LAG_S = 0.030
REFINED_LIMIT_S = 0.0025  # measured error 1.26 ms (2.6-3.6 ms before the per-feature re-query)


@pytest.fixture(scope="module")
def yard_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from mrnc_eval.recording.recorder import SimRequest, simulate_log

    cfg = replace_path(replace_path(Config(), "sim.standstill_s", 3.0), "sim.lidar.packet_profile", "RNG15_RFL8_NIR8")
    return simulate_log(tmp_path_factory.mktemp("yard") / "yard_s3.mcap", cfg,
                        SimRequest(scene="yard", path="circle", duration_s=40.0, lidar="os0-32", columns=512,
                                   seed=3, profile="field"))


def _estimate(log: Path, refine_s: float) -> float:
    from mrnc_eval.io import open_log
    from mrnc_eval.slam.mapping_interval import MappingInterval
    from mrnc_eval.slam.replay import run_slam

    cfg = replace_path(replace_path(Config(), "slam.imu.refine_time_offset_s", refine_s), "slam.imu.time_offset_from",
                       "online")
    with open_log(log) as lg:
        imu = lg.imu()
        out = run_slam(lg.sweeps(keep=MappingInterval(interval_s=cfg.slam.mapping_interval_s).take),
                       replace(imu, stamps=imu.stamps + TRUE_LAG_S - cfg.sim.field.clock.imu_offset_s), cfg.slam,
                       sensor_to_imu=lg.transform("os_sensor", "os_imu"))
    assert out.imu_time_offset_s is not None
    return out.imu_time_offset_s


def test_a_30_ms_lag_applied_during_the_run_is_read_within_2_5_ms_and_not_without(yard_log: Path) -> None:
    once = _estimate(yard_log, 0.0)
    refined = _estimate(yard_log, 10.0)
    print(f"\nIMU lag 30 ms: one estimate after the run {once * 1e3:.2f} ms, applied every 10 s "
          f"{refined * 1e3:.2f} ms")
    assert abs(refined - TRUE_LAG_S) < REFINED_LIMIT_S
    assert abs(once - TRUE_LAG_S) > REFINED_LIMIT_S  # negative control: without applying it under-reads (3.94 ms)


def test_two_rematched_passes_read_a_30_ms_lag_within_2_ms_and_one_online_pass_does_not(
        yard_log: Path, tmp_path: Path) -> None:
    """Through the command (the IMU 25 ms later than the field's 5 ms, by a negative
    slam.imu.time_offset_s; calibrated wheels, field GNSS). Measured (fifth session, the wheels' guess
    blended with the gyro from the first bin): re-match (slam.imu.time_offset_from=rematch, the default;
    at most 2,000 edge and 2,000 surface points a kept sweep) one pass 27.92 ms, two passes 29.14 ms;
    online poses one pass 23.71 ms, two passes 27.92 ms. The online poses' second pass is no longer
    asserted: the gyro-blended wheel guess carries the lagging IMU's timing into the online poses (before
    that blend: 29.21 ms), not into the re-match (over yard and forest seeds 3-5 with calibrated wheels,
    re-match 17 of 18 within 2 ms with the blend, 14 without; docs/simulation.md). Earlier: re-match one
    pass 28.80 ms, two 29.46 ms; every point of the kept sweeps 27.91 / 29.83 ms."""
    from mrnc_eval.commands import slam

    def offset(passes: int, source: str) -> float:
        cfg = replace_path(replace_path(Config(), "slam.imu.time_offset_s", -(TRUE_LAG_S - 0.005)),
                           "slam.imu.time_offset_passes", passes)
        cfg = replace_path(cfg, "slam.imu.time_offset_from", source)
        r = slam.run_log(yard_log, cfg, tmp_path / f"{source}{passes}")
        return next(m.value for m in r.metrics if m.name == "imu_time_offset_s")

    found = {(n, source): offset(n, source) for source in ("rematch", "online") for n in (1, 2)}
    print("\nIMU lag 30 ms: " + ", ".join(f"{source} {n} pass(es) {v * 1e3:.2f} ms"
                                         for (n, source), v in found.items()))
    err = {k: abs(v - TRUE_LAG_S) for k, v in found.items()}
    assert err[2, "rematch"] < 0.002  # the bound (measured 0.86 ms off; standard error ~1 ms)
    assert err[1, "online"] > 0.003  # negative control: one pass under-reads the lag (measured 6.3 ms)
    assert err[1, "rematch"] < err[1, "online"] - 0.002  # the re-match reads more of it in one pass (4.2 ms)
