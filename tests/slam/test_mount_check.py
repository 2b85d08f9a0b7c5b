"""The mount check (slam/mount_check.py) on synthetic drives with a known mount error: the base
poses a SLAM reports are the LiDAR's true poses through the written mount, so a rotated mount
shows the motion off the base x axis."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mrnc_eval.slam.config import MountCheckConfig
from mrnc_eval.slam.mount_check import mount_check

RATE_HZ = 5.0  # the final trajectory's rate at the default mapping interval


def _drive(seed: int, *, turn_rad_s: float = 0.0, slip_deg_per_rad_s: float = 0.0,
           pitch_noise_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """True base poses (N, 4, 4) of a 60 s drive at 1 m/s over gentle hills: straight stretches and
    turns at turn_rad_s; in turns the base side-slips by slip_deg_per_rad_s x yaw rate (skid-steer)."""
    rng = np.random.default_rng(seed)
    fine = 200.0  # integration rate, Hz; the poses are every (fine / RATE_HZ)-th
    t = np.arange(0.0, 60.0, 1.0 / fine)
    yaw_rate = np.where((t % 20.0) > 14.0, turn_rad_s, 0.0)
    yaw = np.cumsum(yaw_rate) / fine
    slope = np.radians(3.0) * np.sin(2 * np.pi * t / 25.0)  # the ground's pitch, rad
    slip = np.radians(slip_deg_per_rad_s) * yaw_rate
    v = np.stack([np.cos(slope) * np.cos(yaw + slip), np.cos(slope) * np.sin(yaw + slip), np.sin(slope)], axis=1)
    pos = np.cumsum(v, axis=0) / fine
    every = slice(None, None, int(fine / RATE_HZ))
    t, yaw, slope, pos = t[every], yaw[every], slope[every], pos[every]
    att = Rotation.from_euler("ZY", np.stack([yaw, -slope], axis=1))
    poses = np.tile(np.eye(4), (t.size, 1, 1))
    poses[:, :3, :3] = att.as_matrix()
    poses[:, :3, 3] = pos + rng.normal(0.0, 0.003, pos.shape)  # SLAM's position noise, m
    jitter = Rotation.from_rotvec(rng.normal(0.0, np.radians(pitch_noise_deg + 0.02), (t.size, 3)))
    poses[:, :3, :3] = (att * jitter).as_matrix()
    return t, poses


def _as_estimated(poses: np.ndarray, written: np.ndarray, error_rpy_deg: tuple[float, float, float]) -> np.ndarray:
    """The base poses a SLAM reports when the LiDAR really sits at written x error (error: true
    relative to written, LiDAR axes): the LiDAR's true poses through the written mount."""
    true = written.copy()
    true[:3, :3] = written[:3, :3] @ Rotation.from_euler("xyz", error_rpy_deg, degrees=True).as_matrix()
    return poses @ true @ np.linalg.inv(written)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_known_mount_error_is_recovered_and_flagged(seed: int) -> None:
    t, poses = _drive(seed, turn_rad_s=0.1)
    est = _as_estimated(poses, np.eye(4), (0.3, -0.4, 0.5))
    check = mount_check(t, est, np.eye(3), MountCheckConfig())
    # measured: within 0.01 deg of (-0.4, +0.5) at sigma ~0.005 deg; the truth within 0.03 deg
    assert check.pitch_deg == pytest.approx(-0.4, abs=0.03)
    assert check.yaw_deg == pytest.approx(0.5, abs=0.03)
    assert check.verdict == "misaligned"
    assert len(check.reasons) == 2
    assert 0.0 < check.pitch_sigma_deg < 0.05
    assert 0.0 < check.yaw_sigma_deg < 0.05
    assert check.correction_rpy_deg[1:] == pytest.approx((-0.4, 0.5), abs=0.03)
    assert check.correction_rpy_deg[0] == pytest.approx(0.0, abs=0.01)  # roll is not observable


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_true_mount_is_not_flagged(seed: int) -> None:
    """Negative control of the test above: the same drives through the true mount."""
    t, poses = _drive(seed, turn_rad_s=0.1)
    check = mount_check(t, poses, np.eye(3), MountCheckConfig())
    assert abs(check.pitch_deg) < 0.03
    assert abs(check.yaw_deg) < 0.03
    assert check.verdict == "ok"
    assert not check.reasons
    assert check.correction_rpy_deg == (0.0, 0.0, 0.0)


def test_a_small_error_within_its_noise_is_not_flagged() -> None:
    """Pitch noise of 0.5 deg per pose: 0.1 deg of error is below flag_deg and not flagged; 1 deg is."""
    t, poses = _drive(0, pitch_noise_deg=0.5)
    cfg = MountCheckConfig()
    assert mount_check(t, _as_estimated(poses, np.eye(4), (0.0, 0.1, 0.0)), np.eye(3), cfg).verdict == "ok"
    big = mount_check(t, _as_estimated(poses, np.eye(4), (0.0, 1.0, 0.0)), np.eye(3), cfg)
    assert big.verdict == "misaligned"
    assert big.pitch_deg == pytest.approx(1.0, abs=3 * big.pitch_sigma_deg + 0.02)


def test_side_slip_in_turns_is_left_out() -> None:
    """A skid-steer side-slipping 20 deg per rad/s in 0.5 rad/s turns (10 deg off its x axis there):
    the yaw-rate limit leaves the turns out; without it (negative control) the slip reads as yaw."""
    t, poses = _drive(0, turn_rad_s=0.5, slip_deg_per_rad_s=20.0)
    check = mount_check(t, poses, np.eye(3), MountCheckConfig())
    assert abs(check.yaw_deg) < 0.15
    assert check.verdict == "ok"
    loose = mount_check(t, poses, np.eye(3), MountCheckConfig(max_yaw_rate_rad_s=3.0))
    assert abs(loose.yaw_deg) > 1.0  # measured -3.0 deg (its jackknife sigma is large: the turns sit in few blocks)


def test_the_correction_is_in_lidar_axes_and_reversing_reads_the_same() -> None:
    """A LiDAR mounted turned 90 deg about z and driven backwards: the correction right-multiplied
    onto the written mount gives back the true mount's pitch and yaw."""
    t, poses = _drive(1)
    back = poses.copy()
    back[:, :3, 3] = poses[::-1, :3, 3]  # the same path driven in reverse, facing the same way
    back[:, :3, :3] = poses[::-1, :3, :3]
    written = np.eye(4)
    written[:3, :3] = Rotation.from_euler("z", 90.0, degrees=True).as_matrix()
    for drive in (poses, back):
        est = _as_estimated(drive, written, (-0.4, 0.0, 0.5))  # roll about the LiDAR's x = the base's y
        check = mount_check(t, est, written[:3, :3], MountCheckConfig())
        assert check.pitch_deg == pytest.approx(-0.4, abs=0.03)
        assert check.yaw_deg == pytest.approx(0.5, abs=0.03)
        assert check.correction_rpy_deg == pytest.approx((-0.4, 0.0, 0.5), abs=0.03)


def test_standing_still_is_insufficient() -> None:
    t, poses = _drive(0)
    poses[:, :3, 3] = poses[:1, :3, 3]
    check = mount_check(t, poses, np.eye(3), MountCheckConfig())
    assert check.verdict == "insufficient"
    assert check.samples == 0
    assert np.isnan(check.pitch_deg)
    assert mount_check(t[:2], poses[:2], np.eye(3), MountCheckConfig()).verdict == "insufficient"


def test_the_slam_command_reports_a_mount_rotated_by_the_config(yard_log: Path, tmp_path: Path) -> None:
    """The ideal-profile yard line (true mount in /tf_static): no finding; with the mount turned by
    slam.sensor.mount_rpy_correction_deg = 1 deg of pitch (a wrong correction) the run flags pitch
    -1 deg and tells the value that undoes it (about 0)."""
    from mrnc_eval.commands.slam import run_log
    from mrnc_eval.config import Config, replace_path, replace_paths

    cfg = replace_paths(Config(), {"slam.gps.enabled": False, "slam.mount_check.min_samples": 10,
                                   "slam.mount_check.blocks": 5, "slam.mount_check.min_distance_m": 1.0})
    ok = run_log(yard_log, cfg, tmp_path / "ok")
    assert ok.extra["mount_check"]["verdict"] == "ok", ok.extra["mount_check"]
    assert not any("mount" in w for w in ok.warnings)
    bad = run_log(yard_log, replace_path(cfg, "slam.sensor.mount_rpy_correction_deg", (0.0, 1.0, 0.0)),
                  tmp_path / "bad")
    check = bad.extra["mount_check"]
    assert check["verdict"] == "misaligned", check
    assert check["pitch_deg"] == pytest.approx(-1.0, abs=0.3)  # measured -0.95 +- 0.12 (0.05 +- 0.12 without)
    (text,) = [w for w in bad.warnings if "mount" in w]
    assert "mount_rpy_correction_deg=[" in text
    total = [float(x) for x in text.rsplit("=[", 1)[1].rstrip("]").split(",")]
    assert total[1] == pytest.approx(0.0, abs=0.3)
    assert bad.metric("mount_pitch_error_deg") is not None



def test_the_slam_command_line_prints_the_run_s_findings(yard_log: Path, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    """A run's findings (here the mount check's) reach the terminal on stderr, named by the log, not
    only result.json and the report; -q keeps stderr to errors; the summary line stays on stdout."""
    from mrnc_eval.cli import main

    sets = [f"--set={kv}" for kv in ("slam.gps.enabled=false", "slam.mount_check.min_samples=10",
                                     "slam.mount_check.blocks=5", "slam.mount_check.min_distance_m=1.0",
                                     "slam.sensor.mount_rpy_correction_deg=[0,1,0]")]
    assert main(["slam", str(yard_log), "--out", str(tmp_path / "loud"), *sets]) == 0
    loud = capsys.readouterr()
    (said,) = [line for line in loud.err.splitlines() if "LiDAR mount" in line]
    # the 1 deg set is what is wrong (/tf_static is the true mount): the mount named is the one turned by it
    assert (f"{yard_log.stem}: the LiDAR mount (/tf_static's turned by [0.00, 1.00, 0.00] deg by "
            "slam.sensor.mount_rpy_correction_deg before the run) looks off by pitch") in said
    assert "loop closures ->" in loud.out
    assert "LiDAR mount" not in loud.out
    assert main(["-q", "slam", str(yard_log), "--out", str(tmp_path / "quiet"), *sets]) == 0
    assert "LiDAR mount" not in capsys.readouterr().err  # negative control: -q says errors only

def test_an_unflagged_angle_s_correction_is_plain_zero() -> None:
    """Only the flagged yaw enters the correction: the unflagged pitch (-0.1 deg, under flag_deg) is
    0.0, not -0.0 (the run's warning printed `slam.sensor.mount_rpy_correction_deg=[0.00, -0.00, 0.46]`)."""
    t, poses = _drive(0, turn_rad_s=0.1)
    check = mount_check(t, _as_estimated(poses, np.eye(4), (0.0, -0.1, 0.5)), np.eye(3), MountCheckConfig())
    assert [r.split()[0] for r in check.reasons] == ["yaw"]
    assert check.pitch_deg < 0.0
    assert [np.copysign(1.0, c) for c in check.correction_rpy_deg[:2]] == [1.0, 1.0]
    assert f"{check.correction_rpy_deg[1]:.2f}" == "0.00"


def _mount(rpy_deg: tuple[float, float, float], xyz: tuple[float, float, float]) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = Rotation.from_euler("xyz", rpy_deg, degrees=True).as_matrix()
    out[:3, 3] = xyz
    return out


@pytest.mark.parametrize(("lidar_frame", "imu_frame", "on_base"), [
    ("os_sensor", "os_imu", False), ("os_lidar", "os_imu", False), ("os_sensor", "chassis_imu", True)])
def test_the_correction_turns_an_imu_in_the_lidar_with_it_and_leaves_a_chassis_imu_on_the_base(
        lidar_frame: str, imu_frame: str, on_base: bool) -> None:
    """The sample logs' tree (os_imu and os_lidar under os_sensor, chassis_imu under base_link): with
    slam.sensor.mount_rpy_correction_deg the Ouster's own IMU keeps its pose in the LiDAR frame, a
    chassis IMU keeps its pose on the base (base -> corrected LiDAR -> IMU = /tf_static's base -> IMU).
    Negative control: the written LiDAR -> chassis IMU pose puts it 1 deg off its base mount."""
    from mrnc_eval.commands.slam import corrected_mount, imu_in_corrected_sensor
    from mrnc_eval.io.tf_tree import static_pose

    statics = {("base_link", "os_sensor"): _mount((0.0, 0.0, 90.0), (1.2, 0.0, 1.9)),
               ("os_sensor", "os_lidar"): _mount((0.0, 0.0, 180.0), (0.0, 0.0, 0.036)),
               ("os_sensor", "os_imu"): _mount((0.0, 0.0, 0.0), (0.006, -0.012, 0.008)),
               ("base_link", "chassis_imu"): _mount((0.0, 0.0, 0.0), (0.0, 0.0, 0.3))}
    rpy = (0.0, 1.0, 0.0)
    written = static_pose(statics, lidar_frame, imu_frame, where=Path("log"))
    mount = corrected_mount(static_pose(statics, "base_link", lidar_frame, where=Path("log")), rpy)
    got = imu_in_corrected_sensor(written, statics, lidar_frame=lidar_frame, imu_frame=imu_frame, rpy_deg=rpy,
                                  where=Path("log"))
    on_base_pose = static_pose(statics, "base_link", imu_frame, where=Path("log"))
    if on_base:
        np.testing.assert_allclose(mount @ got, on_base_pose, atol=1e-12)
        assert np.degrees(Rotation.from_matrix((mount @ written)[:3, :3].T @ on_base_pose[:3, :3]).magnitude()) \
            == pytest.approx(1.0)
    else:
        np.testing.assert_array_equal(got, written)
    uncorrected = imu_in_corrected_sensor(written, statics, lidar_frame=lidar_frame, imu_frame=imu_frame,
                                          rpy_deg=(0.0, 0.0, 0.0), where=Path("log"))
    np.testing.assert_array_equal(uncorrected, written)


def test_stamps_out_of_order_read_as_in_order() -> None:
    """The poses handed over in reverse stamp order: the same finding (before: an IndexError out of
    searchsorted on unsorted stamps)."""
    t, poses = _drive(0, turn_rad_s=0.1)
    est = _as_estimated(poses, np.eye(4), (0.0, -0.4, 0.5))
    want = mount_check(t, est, np.eye(3), MountCheckConfig())
    got = mount_check(t[::-1], est[::-1], np.eye(3), MountCheckConfig())
    assert got.as_dict() == want.as_dict()


def _checked(error_rpy_deg: tuple[float, float, float], applied: tuple[float, float, float], *,
             by_ground: bool = False, mount_written: bool = True) -> tuple[dict, list]:
    """commands.slam._add_mount_check on the synthetic drive, its base poses those of a LiDAR really
    at /tf_static's mount turned by error_rpy_deg, the run corrected by `applied` (deg): the user's
    slam.sensor.mount_rpy_correction_deg, or with `by_ground` the ground check's (nothing set)."""
    from mrnc_eval.commands.slam import LogInputs, _add_mount_check, corrected_mount
    from mrnc_eval.config import Config, replace_path
    from mrnc_eval.data import Trajectory
    from mrnc_eval.geometry import rotation
    from mrnc_eval.results import RunResult

    t, poses = _drive(0, turn_rad_s=0.1)
    mount = corrected_mount(np.eye(4), applied)
    est = _as_estimated(poses, mount, error_rpy_deg)
    traj = Trajectory(t, est[:, :3, 3], rotation.matrix_to_quat(est[:, :3, :3]), name="lio")
    inputs = LogInputs(duration_s=60.0, base_to_sensor=mount, imu=None, sensor_to_imu=np.eye(4), gnss=None,
                       ground_truth=None, antenna=np.zeros(3), antenna_in_sensor=np.zeros(3), n_sweeps=300,
                       max_sweep_gap_s=0.2, mount_rpy_deg=applied, mount_written=mount_written)
    result = RunResult(kind="slam", log_path="log.mcap", log_id="log", config_hash="0")
    user = (0.0, 0.0, 0.0) if by_ground else applied
    _add_mount_check(result, traj, inputs, replace_path(Config(), "slam.sensor.mount_rpy_correction_deg", user))
    return result.extra.get("mount_check", {}), result.warnings


def test_a_log_without_a_base_link_mount_gets_no_mount_check() -> None:
    """A log whose /tf_static has no base_link -> LiDAR mount (the LiDAR's pose taken as the base): no
    mount to check, so no record and no warning saying /tf_static's mount looks off. Negative control:
    the same motion with a written mount is flagged."""
    record, warnings = _checked((0.0, -0.4, 0.0), (0.0, 0.0, 0.0), mount_written=False)
    assert record == {}
    assert warnings == []
    record, warnings = _checked((0.0, -0.4, 0.0), (0.0, 0.0, 0.0))
    assert record["verdict"] == "misaligned"
    assert len(warnings) == 1


def test_the_suggested_correction_composes_the_applied_one_and_is_offered_only_in_range() -> None:
    """A run corrected by 3 deg of yaw whose LiDAR is still off by -0.4 deg pitch and +0.5 deg yaw:
    metrics.json's suggested_rpy_deg and the warning's value are the applied correction and the new
    one composed (~[0, -0.4, 3.5]); a 20 deg yaw error is beyond the parameter's +-10 deg range: the
    warning says correct /tf_static and offers no value the config would refuse."""
    record, warnings = _checked((0.0, -0.4, 0.5), (0.0, 0.0, 3.0))
    assert record["applied_rpy_deg"] == [0.0, 0.0, 3.0]
    assert record["suggested_rpy_deg"] == pytest.approx([0.0, -0.4, 3.5], abs=0.03)
    (text,) = warnings
    assert text.endswith(", ".join(f"{a:.2f}" for a in record["suggested_rpy_deg"]) + "]")
    record, warnings = _checked((0.0, 0.0, 20.0), (0.0, 0.0, 0.0))
    assert record["suggested_rpy_deg"][2] == pytest.approx(20.0, abs=0.1)
    (text,) = warnings
    assert "mount_rpy_correction_deg=" not in text
    assert "correct /tf_static (by [" in text


@pytest.mark.parametrize("by_ground", [False, True])
def test_the_warning_names_the_mount_the_motion_was_read_through(by_ground: bool) -> None:
    """Run with /tf_static's mount turned by 3 deg of yaw (the user's correction, or the ground check's
    applied by default), the motion reads what is left on top of it (-0.4 pitch): the warning said
    "the LiDAR mount in /tf_static looks off by pitch -0.40", which /tf_static is not; it names the
    corrected mount and who turned it. Negative control: nothing applied names /tf_static."""
    _, warnings = _checked((0.0, -0.4, 0.0), (0.0, 0.0, 3.0), by_ground=by_ground)
    (text,) = warnings
    assert "in /tf_static looks off" not in text
    assert "turned by [0.00, 0.00, 3.00] deg" in text
    assert ("the ground check" in text) == by_ground
    assert ("slam.sensor.mount_rpy_correction_deg before the run" in text) == (not by_ground)
    _, warnings = _checked((0.0, -0.4, 0.0), (0.0, 0.0, 0.0), by_ground=by_ground)
    (text,) = warnings
    assert "the LiDAR mount in /tf_static looks off by pitch" in text
