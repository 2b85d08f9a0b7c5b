"""The ground check of the mount through the run's own input pass (commands.slam._read_inputs) on
simulated 1 s starts of the open line: the field profile's LiDAR sits at /tf_static's mount turned by
roll 0.3, pitch -0.4, yaw 0.5 deg (or as a test sets it). On flat ground the check reads a 1 deg pitch
and the run's mount takes it (by default), a right mount is left alone; on the field terrain's waves it
says "not measurable" and /tf_static stays."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.config import Config, replace_paths

from .open_line import DRIVE

pytestmark = pytest.mark.slow


def _start(tmp_path: Path, *, roughness_m: float, error_rpy_deg: tuple[float, float, float]) -> Path:
    from mrnc_eval.recording.recorder import SimRequest, simulate_log

    cfg = replace_paths(Config(), {**DRIVE, "sim.field.world.terrain_roughness_m": roughness_m,
                                   "sim.field.calibration.lidar_rpy_error_deg": error_rpy_deg})
    return simulate_log(tmp_path / "start.mcap", cfg,
                        SimRequest(scene="open_field", path="line", duration_s=1.0, lidar="os0-32", columns=512,
                                   seed=3, profile="field"))


def _inputs(log: Path, sets: dict[str, object]):
    from mrnc_eval.commands.slam import _read_inputs
    from mrnc_eval.io.reader import open_log

    with open_log(log) as lg:
        return _read_inputs(lg, log, replace_paths(Config(), sets)), lg.transform("base_link", "os_sensor")


def test_flat_ground_recovers_a_one_degree_pitch_and_the_run_takes_it(tmp_path: Path) -> None:
    """Positive control: /tf_static 1 deg off in pitch (the LiDAR mounted level, so base axes = LiDAR axes)."""
    log = _start(tmp_path, roughness_m=0.0, error_rpy_deg=(0.0, 1.0, 0.0))
    inputs, written = _inputs(log, {})
    g = inputs.ground_mount
    assert g is not None
    assert g.verdict == "misaligned"
    # measured (seed 3): pitch +1.06 +- 0.15, roll -0.03 +- 0.11 deg
    assert g.pitch_deg == pytest.approx(1.0, abs=max(2.0 * g.pitch_sigma_deg, 0.2))
    assert abs(g.roll_deg) < 0.3
    assert inputs.mount_rpy_deg == g.correction_rpy_deg
    assert g.correction_rpy_deg[1] == pytest.approx(g.pitch_deg, abs=0.01)
    assert not np.allclose(inputs.base_to_sensor[:3, :3], written[:3, :3])
    # the user's correction wins over the ground's
    user, _ = _inputs(log, {"slam.sensor.mount_rpy_correction_deg": (0.0, 0.9, 0.0)})
    assert user.mount_rpy_deg == (0.0, 0.9, 0.0)
    # a dense sweep is read thinned (every k-th point; a 6,400-point OS0-32 sweep whole by default): the
    # same reading within its sigma from a third of the points
    thin, _ = _inputs(log, {"slam.ground_mount.max_points_per_sweep": 2000})
    assert thin.ground_mount is not None
    assert thin.ground_mount.points < 0.5 * g.points
    assert thin.ground_mount.pitch_deg == pytest.approx(1.0, abs=max(2.0 * thin.ground_mount.pitch_sigma_deg, 0.2))
    # apply off: a check only, /tf_static kept
    kept, _ = _inputs(log, {"slam.ground_mount.apply": False})
    np.testing.assert_array_equal(kept.base_to_sensor, written)


def test_flat_ground_and_the_true_mount_leave_tf_static_alone(tmp_path: Path) -> None:
    """Negative control: /tf_static is the true mount."""
    inputs, written = _inputs(_start(tmp_path, roughness_m=0.0, error_rpy_deg=(0.0, 0.0, 0.0)), {})
    assert inputs.ground_mount is not None
    assert inputs.ground_mount.verdict == "ok"
    np.testing.assert_array_equal(inputs.base_to_sensor, written)


def test_the_field_terrain_is_not_measurable_and_the_mount_stays(tmp_path: Path) -> None:
    """Negative control: the field terrain's 0.04 m waves under the field profile's mount error
    (measured: roll +4.71 +- 1.66, pitch -0.39 +- 1.36 deg)."""
    inputs, written = _inputs(_start(tmp_path, roughness_m=0.04, error_rpy_deg=(0.3, -0.4, 0.5)), {})
    assert inputs.ground_mount is not None
    assert inputs.ground_mount.verdict == "not measurable"
    np.testing.assert_array_equal(inputs.base_to_sensor, written)
