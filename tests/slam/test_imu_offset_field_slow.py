"""Slow (issue 28 item 4): the IMU-LiDAR offset read within 2 ms of an 8 and a 30 ms lag on the claims
matrix's forest loop (report seeds 3-5) and yard circle (seed 3): field profile, OS0-32 x 512, 40 s, exact
wheels, float GNSS; the IMU made later in memory by a negative slam.imu.time_offset_s (the field's own
5 ms plus the rest). Run:
    .venv/bin/python -m pytest -m slow tests/slam/test_imu_offset_field_slow.py -s

One pass reads a lag short (its deskew and keyframes ran on the lagged IMU: forest seeds 0-5 1.5 ms short
on average, 4 of 12 lags more than 2 ms); the second pass, the default while the offset left stands out,
runs with the first estimate applied and reads what is left. Measured (twelfth session; error in ms, one
pass / two passes): forest s3 -2.79 / -1.78 at 8 ms, -1.19 / -1.64 at 30 ms; s4 -1.58 / -1.36, -3.04 /
-1.23; s5 -2.82 / -0.46, -0.80 / -1.84; yard s3 +0.07 / +0.11, -1.72 / -0.13.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from mrnc_eval.config import Config, replace_paths
from tests.slam.open_line import simulate_structured

pytestmark = pytest.mark.slow
LIMIT_S = 0.002  # the bound
FIELD_LAG_S = 0.005  # sim.field.clock.imu_offset_s: the field profile's IMU is this late already
CASES = [("forest", 3), ("forest", 4), ("forest", 5), ("yard", 3)]


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[str, int], Path]:
    folder = tmp_path_factory.mktemp("offset")
    return {(scene, seed): simulate_structured(folder / f"{scene}_ideal_float_s{seed}.mcap", scene, seed,
                                               {"sim.wheels.model": "exact"}) for scene, seed in CASES}


def _offset(log: Path, lag_s: float, passes: int, out: Path) -> float:
    from mrnc_eval.commands.slam import run_log

    assert Config().sim.field.clock.imu_offset_s == FIELD_LAG_S
    cfg = replace_paths(Config(), {"slam.imu.time_offset_s": -(lag_s - FIELD_LAG_S),
                                   "slam.imu.time_offset_passes": passes})
    m = run_log(log, cfg, out, method="lio").metric("imu_time_offset_s")
    assert m is not None
    return float(m.value)


def test_8_and_30_ms_lags_are_read_within_2_ms_in_two_passes_and_not_in_one(logs: dict[tuple[str, int], Path],
                                                                           tmp_path: Path) -> None:
    errors: dict[int, dict[tuple[str, int, float], float]] = {1: {}, 2: {}}
    for (scene, seed), log in logs.items():
        for lag in (0.008, 0.030):
            for passes in (1, 2):
                found = _offset(log, lag, passes, tmp_path / f"{scene}{seed}_{lag * 1e3:.0f}_{passes}")
                errors[passes][scene, seed, lag] = found - lag
    for key in errors[2]:
        print(f"{key[0]} s{key[1]} lag {key[2] * 1e3:.0f} ms: error one pass {errors[1][key] * 1e3:+.2f} ms, "
              f"two passes {errors[2][key] * 1e3:+.2f} ms")
    assert all(abs(e) < LIMIT_S for e in errors[2].values())
    # negative control: one pass misses the bound on some lags (measured 3 of 8)
    assert sum(abs(e) >= LIMIT_S for e in errors[1].values()) >= 2
