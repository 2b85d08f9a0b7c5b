"""Slow (issue 28): the GNSS/INS in graph #2 (slam.gps.ins, off by default) on the open line of the
claims matrix without wheel odometry (field profile, OS0-32 x 512, 40 s, float GNSS; the calibrated
-wheel log with slam.wheel_odom.enabled=false), seed 2. Run:
    .venv/bin/python -m pytest -m slow tests/slam/test_gnss_ins_slow.py -s

Seed 2 is a tuning seed: on the report seeds 3-5 the GNSS/INS does not hold this cell yet
(docs/simulation.md, "GNSS/INS in graph #2"); this test guards what it does where it works. Held at
about 2x what was measured; the negative control is the same log without it and without the GNSS track
(slam.gps.track=never: IMU dead reckoning along the degenerate directions): it must fail the same
limit. (The default since the third session, the GNSS track, reads 0.84 m here, on par with it.)
"""

from __future__ import annotations

from pathlib import Path

import pytest

from mrnc_eval.config import Config, replace_paths
from tests.slam.open_line import simulate_open_line

pytestmark = pytest.mark.slow

NO_WHEELS = {"slam.wheel_odom.enabled": False}
# measured (/tmp/wheels_logs/line_calibrated_float_s2.mcap, benchmarks/wheel_gnss_matrix.py's log): online APE
# 0.769 m, end drift 0.85 m with slam.gps.ins=without_wheels (0.739 m / 1.27 m at main 8bad290); 7.5 m (drift
# 44 m) without it and without the GNSS track
APE_LIMIT_M = 1.5


@pytest.fixture(scope="module")
def line_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate_open_line(tmp_path_factory.mktemp("gnss_ins") / "line_calibrated_float_s2.mcap", seed=2)


def _run(log: Path, out: Path, rules: dict[str, object]) -> dict[str, float]:
    from mrnc_eval.commands.slam import run_log

    r = run_log(log, replace_paths(Config(), rules), out, method="lio")
    return {m.name: float(m.value) for m in r.metrics if isinstance(m.value, (int, float))}


def test_gnss_ins_holds_the_open_line_without_wheels(line_log: Path, tmp_path: Path) -> None:
    m = _run(line_log, tmp_path / "ins", {**NO_WHEELS, "slam.gps.ins": "without_wheels"})
    print(f"GNSS/INS: online APE {m['ape_online_rmse_m']:.3f} m, end drift {m['end_drift_online_m']:.2f} m")
    assert m["ape_online_rmse_m"] < APE_LIMIT_M

    before = _run(line_log, tmp_path / "off", {**NO_WHEELS, "slam.gps.track": "never"})
    print(f"without it or the GNSS track: {before['ape_online_rmse_m']:.3f} m, {before['end_drift_online_m']:.2f} m")
    assert not (before["ape_online_rmse_m"] < APE_LIMIT_M)
