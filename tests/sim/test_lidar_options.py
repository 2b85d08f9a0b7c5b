"""`simulate`'s --lidar, --columns and --rate set the sensor whatever sim.lidar.* says (tenth session: the
stress logs' `--set sim.lidar.rate_hz=20` with the default --rate wrote 10 Hz logs identical to the plain
ones, and nothing said so). A --set the options would silently override is refused with exit 2, the key,
the option and the value to use, and no log; a --set that agrees with the options (the control) passes."""

from __future__ import annotations

from pathlib import Path

import pytest

from mrnc_eval.cli import main
from mrnc_eval.config import Config, replace_paths
from mrnc_eval.errors import UsageError
from mrnc_eval.recording.recorder import SimRequest, check_lidar_sets


def test_a_lidar_set_the_options_override_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "x.mcap"
    assert main(["simulate", str(out), "--lidar", "os0-32", "--columns", "512", "--duration", "2",
                 "--set", "sim.lidar.rate_hz=20", "--set", "sim.lidar.beams=64"]) == 2
    err = capsys.readouterr().err
    assert "sim.lidar.rate_hz=20 is set by --rate (10): use --rate 20" in err
    assert "sim.lidar.beams=64 is set by --lidar (32): use --lidar os0-64" in err
    assert not any(tmp_path.iterdir())  # no log, no ground truth


def test_a_lidar_set_that_agrees_with_the_options_passes() -> None:
    request = SimRequest(scene="yard", path="circle", duration_s=2.0, lidar="os0-64", columns=1024, rate_hz=20.0)
    agreeing = replace_paths(Config(), {"sim.lidar.rate_hz": 20.0, "sim.lidar.beams": 64, "sim.lidar.columns": 1024})
    check_lidar_sets(agreeing, request)  # the control: no error
    check_lidar_sets(Config(), request)  # the defaults say nothing
    with pytest.raises(UsageError, match=r"sim\.lidar\.columns=2048 is set by --columns \(1024\)"):
        check_lidar_sets(replace_paths(Config(), {"sim.lidar.columns": 2048}), request)
