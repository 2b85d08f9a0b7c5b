"""What the SLAM result says it measured: online vs smoothed trajectories, the Table I choice,
kiss-icp's deskew on throttled logs, map quality, the IMU time offset."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.config import Config, replace_path
from mrnc_eval.io.trajectory_files import read_tum
from mrnc_eval.results import read_result
from tests.needs import need_module


def _value(result, name: str) -> float:
    metric = result.metric(name)
    assert metric is not None, f"{name} missing from the result"
    return float(metric.value)


def test_without_corrections_online_and_smoothed_coincide_and_table_follows_the_option(yard_log: Path,
                                                                                       tmp_path: Path) -> None:
    """Negative control of the online/smoothed split: with no loop closure and no GNSS nothing
    corrects a keyframe after the fact, so both trajectories are the same; Table I takes the one
    slam.table_trajectory names."""
    from mrnc_eval.commands.slam import run_log

    cfg = replace_path(replace_path(Config(), "slam.loop.enabled", False), "slam.gps.enabled", False)
    online_run = run_log(yard_log, cfg, tmp_path / "online")
    smoothed_run = run_log(yard_log, replace_path(cfg, "slam.table_trajectory", "smoothed"), tmp_path / "smoothed")
    online = read_tum(tmp_path / "online" / "trajectory_online.tum")
    smoothed = read_tum(tmp_path / "online" / "trajectory.tum")
    np.testing.assert_array_equal(online.stamps, smoothed.stamps)
    np.testing.assert_allclose(online.positions, smoothed.positions, atol=1e-6)
    assert _value(online_run, "ape_online_rmse_m") == pytest.approx(_value(online_run, "ape_rmse_m"), abs=1e-6)
    (table,) = online_run.tables
    assert "online" in table.title
    assert table.cells[0][0] == _value(online_run, "ape_online_rmse_m")
    (table,) = smoothed_run.tables
    assert "smoothed" in table.title
    assert table.cells[0][0] == _value(smoothed_run, "ape_rmse_m")


def test_kiss_icp_deskew_is_off_on_a_throttled_log_and_on_at_full_rate(throttled_log: Path, yard_log: Path,
                                                                        tmp_path: Path) -> None:
    """1 Hz sweeps of a 10 Hz sensor: kiss-icp's deskew would spread 1 s of motion over 0.1 s, so
    it runs without deskew and the result says so. The 10 Hz log (negative control) keeps it."""
    need_module("kiss_icp", "kiss-icp is not installed (pip install 'mrnc-eval[test]'): the peer comparison cannot run")
    from mrnc_eval.commands.slam import run_log

    throttled = run_log(throttled_log, Config(), tmp_path / "throttled", method="kiss-icp")
    assert throttled.extra["deskew"] is False
    assert any("deskew off" in w and "1.5 sweep periods" in w for w in throttled.warnings)
    assert read_result(tmp_path / "throttled").extra["deskew"] is False
    full_rate = run_log(yard_log, Config(), tmp_path / "full", method="kiss-icp")
    assert full_rate.extra["deskew"] is True
    assert not any("deskew" in w for w in full_rate.warnings)


def _rocking(t: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (rad) of a machine rocking on rough ground while turning slowly."""
    return np.c_[0.05 * np.sin(2 * np.pi * 0.7 * t), 0.04 * np.sin(2 * np.pi * 1.1 * t + 1.0), 0.1 * t]


@pytest.mark.parametrize("lag_s", [0.0, 0.008, -0.005])
def test_time_offset_estimator_recovers_a_known_lag(lag_s: float) -> None:
    """Gyro of the rocking motion at 100 Hz stamped `lag_s` late, LiDAR rotations at 6.7 Hz with
    0.05 deg noise: the estimate is within 1 ms of the lag (lag 0 is the negative control)."""
    from scipy.spatial.transform import Rotation

    from mrnc_eval.data import ImuSeries
    from mrnc_eval.slam.imu import imu_track
    from mrnc_eval.slam.time_offset import estimate_imu_time_offset

    rng = np.random.default_rng(1)
    t_imu = np.arange(0.0, 60.0, 0.01)
    h = 1e-4
    rate = (Rotation.from_euler("xyz", _rocking(t_imu - h)).inv()
            * Rotation.from_euler("xyz", _rocking(t_imu + h))).as_rotvec() / (2 * h)
    imu = ImuSeries(t_imu + lag_s, np.tile([0.0, 0.0, 9.81], (t_imu.size, 1)), rate + [0.002, -0.001, 0.0005])
    track = imu_track(imu, np.eye(3))
    t_lidar = np.arange(1.0, 59.0, 0.15)
    noise = Rotation.from_rotvec(rng.normal(0.0, np.radians(0.05), (t_lidar.size, 3)))
    rotations = (Rotation.from_euler("xyz", _rocking(t_lidar)) * noise).as_matrix()
    estimate = estimate_imu_time_offset(t_lidar, rotations, track)
    assert estimate is not None
    assert abs(estimate - lag_s) < 1e-3
    # its standard error: the estimate within 4 of it; a quarter of the log gives about twice as much
    from mrnc_eval.slam.time_offset import imu_time_offset

    full, short = imu_time_offset(t_lidar, rotations, track), imu_time_offset(t_lidar[:97], rotations[:97], track)
    assert full is not None
    assert short is not None
    assert abs(full.offset_s - lag_s) < 4 * full.sigma_s
    assert 1.5 < short.sigma_s / full.sigma_s < 3.0


@pytest.mark.parametrize("lag_s", [0.0, 0.008, 0.03])
def test_an_axis_the_lidar_times_badly_does_not_set_the_offset(lag_s: float) -> None:
    """As on the field logs, where the SLAM's roll alone read a lag 10 ms off (yard seed 1, per-axis
    best shifts -9.5 / +1.0 / -2.5 ms; rate std 0.02 / 0.03 / 0.06 rad/s): LiDAR roll 10 ms late
    with 0.1 deg noise, pitch and yaw right with 0.02 deg. Each axis weighted by its own residual,
    the estimate is 1.6-3.3 ms off for lags of 0-30 ms (seeds 2-4); summed as they are (the
    negative control), the roll pulls it 9-12 ms off. The weighting shrinks such a pull; it does not
    remove it."""
    from scipy.spatial.transform import Rotation

    from mrnc_eval.data import ImuSeries
    from mrnc_eval.slam.imu import imu_track
    from mrnc_eval.slam.time_offset import estimate_imu_time_offset

    rng = np.random.default_rng(2)
    t_imu = np.arange(0.0, 40.0, 0.01)
    h = 1e-4

    def motion(t: np.ndarray) -> np.ndarray:
        return np.c_[0.004 * np.sin(2 * np.pi * 1.7 * t), 0.006 * np.sin(2 * np.pi * 1.1 * t + 1.0),
                     0.3 * np.sin(0.4 * t)]

    rate = (Rotation.from_euler("xyz", motion(t_imu - h)).inv()
            * Rotation.from_euler("xyz", motion(t_imu + h))).as_rotvec() / (2 * h)
    track = imu_track(ImuSeries(t_imu + lag_s, np.tile([0.0, 0.0, 9.81], (t_imu.size, 1)), rate), np.eye(3))
    t_lidar = np.arange(1.0, 39.0, 0.2)
    rpy = motion(t_lidar)
    rpy[:, 0] = motion(t_lidar - 0.010)[:, 0] + rng.normal(0.0, np.radians(0.1), t_lidar.size)
    rpy[:, 1:] += rng.normal(0.0, np.radians(0.02), (t_lidar.size, 2))
    rotations = Rotation.from_euler("xyz", rpy).as_matrix()
    weighted = estimate_imu_time_offset(t_lidar, rotations, track)
    summed = estimate_imu_time_offset(t_lidar, rotations, track, axis_weights=False)
    assert weighted is not None
    assert summed is not None
    assert abs(weighted - lag_s) < 4e-3
    assert abs(summed - lag_s) > 8e-3


def test_time_offset_needs_rotation() -> None:
    from mrnc_eval.data import ImuSeries
    from mrnc_eval.slam.imu import imu_track
    from mrnc_eval.slam.time_offset import estimate_imu_time_offset

    t = np.arange(0.0, 20.0, 0.01)
    track = imu_track(ImuSeries(t, np.tile([0.0, 0.0, 9.81], (t.size, 1)), np.zeros((t.size, 3))), np.eye(3))
    stamps = np.arange(1.0, 19.0, 0.15)
    assert estimate_imu_time_offset(stamps, np.tile(np.eye(3), (stamps.size, 1, 1)), track) is None


def test_time_offset_of_three_sweeps_with_one_inside_the_imu_span_is_none_without_warnings() -> None:
    """The real recording's case: three sweeps, one more than the search window inside the IMU span
    (numpy warned "Mean of empty slice" on the median of no interval)."""
    import warnings

    from mrnc_eval.data import ImuSeries
    from mrnc_eval.slam.imu import imu_track
    from mrnc_eval.slam.time_offset import estimate_imu_time_offset

    t = np.arange(0.0, 0.5, 0.01)
    track = imu_track(ImuSeries(t, np.tile([0.0, 0.0, 9.81], (t.size, 1)), np.zeros((t.size, 3))), np.eye(3))
    stamps = np.array([0.05, 0.25, 0.45])  # only 0.25 is 0.1 s clear of both ends
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert estimate_imu_time_offset(stamps, np.tile(np.eye(3), (3, 1, 1)), track) is None


def test_map_quality_rises_with_blur() -> None:
    """A plane sampled on a 5 cm grid: plane variance ~ 0 and entropy low; the same plane with
    2 cm of noise across it (a blurred map) has plane variance ~ (2 cm)^2 and higher entropy."""
    from mrnc_eval.slam.map_quality import map_quality

    g = np.arange(-3.0, 3.0, 0.05)
    x, y = np.meshgrid(g, g)
    sharp = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    blurred = sharp + np.c_[np.zeros((x.size, 2)), np.random.default_rng(0).normal(0.0, 0.02, x.size)]
    a = map_quality(sharp, 0.3)
    b = map_quality(blurred, 0.3)
    assert a is not None
    assert b is not None
    assert a.mean_plane_variance_m2 < 1e-12
    assert b.mean_plane_variance_m2 == pytest.approx(0.02 ** 2, rel=0.3)
    assert b.mean_map_entropy > a.mean_map_entropy + 1.0 or not np.isfinite(a.mean_map_entropy)


def test_time_offset_is_not_estimated_from_throttled_sweeps() -> None:
    """1 s between mapped sweeps (a throttled log): the rotation increments average a whole second
    and cannot time milliseconds; no estimate rather than a misleading one."""
    from scipy.spatial.transform import Rotation

    from mrnc_eval.data import ImuSeries
    from mrnc_eval.slam.imu import imu_track
    from mrnc_eval.slam.time_offset import estimate_imu_time_offset

    t = np.arange(0.0, 60.0, 0.01)
    h = 1e-4
    rate = (Rotation.from_euler("xyz", _rocking(t - h)).inv()
            * Rotation.from_euler("xyz", _rocking(t + h))).as_rotvec() / (2 * h)
    track = imu_track(ImuSeries(t, np.tile([0.0, 0.0, 9.81], (t.size, 1)), rate), np.eye(3))
    stamps = np.arange(1.0, 59.0, 1.0)
    rotations = Rotation.from_euler("xyz", _rocking(stamps)).as_matrix()
    assert estimate_imu_time_offset(stamps, rotations, track) is None


def test_time_offset_ignores_poses_that_were_only_the_imu_guess() -> None:
    """Sweeps where scan-to-map did not run (or was degenerate) carry the IMU's own prediction:
    compared with the gyro they would say "no offset". Marked as not measured, they are left out
    and the 8 ms lag is still found; counted in, they drag the estimate towards 0 (negative control)."""
    from scipy.spatial.transform import Rotation

    from mrnc_eval.data import ImuSeries
    from mrnc_eval.slam.imu import imu_track
    from mrnc_eval.slam.time_offset import estimate_imu_time_offset

    lag = 0.008
    t = np.arange(0.0, 60.0, 0.01)
    h = 1e-4
    rate = (Rotation.from_euler("xyz", _rocking(t - h)).inv()
            * Rotation.from_euler("xyz", _rocking(t + h))).as_rotvec() / (2 * h)
    track = imu_track(ImuSeries(t + lag, np.tile([0.0, 0.0, 9.81], (t.size, 1)), rate), np.eye(3))
    stamps = np.arange(1.0, 59.0, 0.15)
    measured = (np.arange(stamps.size) // 20) % 2 == 0  # alternating stretches of 20 sweeps
    truth = Rotation.from_euler("xyz", _rocking(stamps))
    guess = Rotation.from_euler("xyz", _rocking(stamps - lag))  # what the lagged IMU would predict
    rotations = np.where(measured[:, None, None], truth.as_matrix(), guess.as_matrix())
    with_mask = estimate_imu_time_offset(stamps, rotations, track, measured)
    without_mask = estimate_imu_time_offset(stamps, rotations, track)
    assert with_mask is not None
    assert without_mask is not None
    assert abs(with_mask - lag) < 1e-3
    assert abs(without_mask - lag) > 2e-3


def _fake_replays(true_lag: float, kept: float, seen: list[float]):
    """A stand-in for commands.slam._replay: each pass reads (1 - kept) of the lag it is left with."""
    import numpy as np

    from mrnc_eval.slam.output import SlamOutput

    def fake_replay(lg, inputs, cfg, progress, window):
        seen.append(cfg.slam.imu.time_offset_s)
        left = true_lag - cfg.slam.imu.time_offset_s
        return SlamOutput(stamps=np.array([0.0, 1.0]), poses=np.zeros((2, 4, 4)), kf_stamps=np.zeros(0),
                          kf_poses=np.zeros((0, 4, 4)), map_points=np.zeros((0, 3)), timing_ms={}, events=[],
                          warnings=[], n_sweeps=2, wall_s=0.0, imu_time_offset_s=(1 - kept) * left,
                          imu_time_offset_sigma_s=0.001)

    return fake_replay


def test_offset_passes_rerun_while_the_offset_left_stands_out(monkeypatch: pytest.MonkeyPatch) -> None:
    """slam.imu.time_offset_passes: each later pass runs with the offset found so far applied, stops
    once what is left is within 2 ms or 2 standard errors, and reports the sum of all passes."""
    from mrnc_eval.commands import slam as slam_command
    from mrnc_eval.config import Config, replace_path

    applied_seen: list[float] = []
    monkeypatch.setattr(slam_command, "_replay", _fake_replays(0.030, 0.2, applied_seen))
    cfg = replace_path(replace_path(Config(), "slam.imu.time_offset_passes", 5), "slam.mount_check.apply", False)
    out, _ = slam_command._replay_passes(None, None, None, None, cfg, False, None)
    # 30 -> 24 found; 6 left -> 4.8 (28.8); 1.2 left -> 0.96 (< 2 ms: the last pass)
    assert applied_seen == pytest.approx([0.0, 0.024, 0.0288])
    assert out.imu_time_offset_s == pytest.approx(0.0288 + 0.8 * 0.0012)
    assert [e.data["pass"] for e in out.events] == [3]  # each pass's output is its own run's, noted
    one, _ = slam_command._replay_passes(None, None, None, None, replace_path(cfg, "slam.imu.time_offset_passes", 1),
                                         False, None)
    assert one.imu_time_offset_s == pytest.approx(0.024)  # negative control: one pass under-reads


def test_a_flagged_mount_and_an_offset_are_corrected_in_one_second_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """The first pass flags the mount and leaves an offset standing out: the second run carries both
    corrections (not a mount pass followed by its own offset passes), and the output says so."""
    from types import SimpleNamespace

    from mrnc_eval.commands import slam as slam_command
    from mrnc_eval.config import Config

    applied_seen: list[float] = []
    monkeypatch.setattr(slam_command, "_replay", _fake_replays(0.030, 0.0, applied_seen))
    motions = iter([SimpleNamespace(reasons=["pitch -0.40 +- 0.05 deg"])])
    monkeypatch.setattr(slam_command, "_mount_to_apply", lambda out, inputs, cfg: next(motions, None))
    remounted = SimpleNamespace(applied_rpy_deg=(0.0, -0.4, 0.0))
    monkeypatch.setattr(slam_command, "_remounted", lambda read, lg, path, cfg, motion: remounted)
    monkeypatch.setattr(slam_command, "_with_wheel_clock", lambda inputs, cfg: inputs)
    out, inputs = slam_command._replay_passes(None, "x.mcap", None, None, Config(), False, None)
    assert applied_seen == pytest.approx([0.0, 0.030])  # one second run, the offset applied in it
    assert inputs is remounted
    assert out.imu_time_offset_s == pytest.approx(0.030)
    assert [e.kind for e in out.events] == ["mount", "imu_time_offset"]


@pytest.mark.parametrize(("offset_s", "sigma_s", "says"), [
    (0.0058, 0.0009, "IMU-LiDAR time offset 5.8 +- 0.9 ms (> 2 ms): the IMU stamps look late; "
                     "set slam.imu.time_offset_s=0.0058"),
    (-0.0031, None, "IMU-LiDAR time offset -3.1 ms (> 2 ms): the IMU stamps look early"),  # online: no sigma
    (0.0015, 0.0002, None),  # negative controls: within 2 ms, and within 2 standard errors
    (0.0035, 0.0020, None),
])
def test_the_offset_finding_gives_the_standard_error_the_reading_carries(offset_s: float, sigma_s: float | None,
                                                                          says: str | None) -> None:
    """A 40 s log reads its offset to about 1 ms (docs/simulation.md, "Thirteenth session"): the finding
    that asks the user to set slam.imu.time_offset_s says how sure the value is."""
    from mrnc_eval.commands.slam import _add_time_offset
    from mrnc_eval.results import RunResult
    from mrnc_eval.slam.output import SlamOutput

    out = SlamOutput(stamps=np.array([0.0, 1.0]), poses=np.zeros((2, 4, 4)), kf_stamps=np.zeros(0),
                     kf_poses=np.zeros((0, 4, 4)), map_points=np.zeros((0, 3)), timing_ms={}, events=[], warnings=[],
                     n_sweeps=2, wall_s=0.0, imu_time_offset_s=offset_s, imu_time_offset_sigma_s=sigma_s)
    result = RunResult(kind="slam", log_path="x.mcap", log_id="x")
    _add_time_offset(result, out, Config())
    if says is None:
        assert result.warnings == []
        assert [e.kind for e in result.events] == []
    else:
        assert len(result.warnings) == 1
        assert result.warnings[0].startswith(says)
        assert [e.message for e in result.events] == result.warnings
        assert result.events[0].data.get("imu_time_offset_sigma_s") == sigma_s


@pytest.mark.parametrize(("rmse_m", "degenerate", "wheels", "says", "track"), [
    (13.7, 0.82, False, "IMU dead reckoning", False),  # the open line without wheels, RTK fixes
    (13.7, 0.82, True, "the trajectory, not the GNSS", False),
    (13.7, 0.05, False, "check the GNSS", False),  # a LiDAR that held: the fixes or the lever arm are suspect
    (13.7, 0.82, False, "followed the GNSS track from 3.0 s", True),  # the fixes carried x, y: not dead reckoning
    (2.0, 0.82, False, None, False),  # negative control: float fixes 2 m off (the sample logs) say nothing
])
def test_a_trajectory_far_from_the_fixes_is_a_finding_that_names_the_likely_culprit(
        rmse_m: float, degenerate: float, wheels: bool, says: str | None, track: bool) -> None:
    import numpy as np

    from mrnc_eval.commands.slam import _add_gnss_disagreement
    from mrnc_eval.data import GnssSeries
    from mrnc_eval.results import RunResult
    from mrnc_eval.slam.output import SlamEvent, SlamOutput

    n = 50
    gnss = GnssSeries(np.arange(n) * 0.2, np.zeros((n, 3)), np.zeros((n, 3)), np.tile(np.diag([4e-4, 4e-4, 1e-3]),
                                                                                       (n, 1, 1)), np.zeros(3))
    result = RunResult(kind="slam", log_path="x.mcap", log_id="x",
                       extra={"inputs": {"lidar": "/points", **({"wheel_odom": "/odom"} if wheels else {})}})
    out = SlamOutput(stamps=np.arange(10.0), poses=np.zeros((10, 4, 4)), kf_stamps=np.zeros(0),
                     kf_poses=np.zeros((0, 4, 4)), map_points=np.zeros((0, 3)), timing_ms={},
                     events=[SlamEvent(t=3.0, kind="gps", message="GNSS track: ...", data={"gnss_track": "engaged"})]
                     if track else [], warnings=[],
                     n_sweeps=10, wall_s=0.0, degenerate=np.arange(10) < round(10 * degenerate))
    _add_gnss_disagreement(result, gnss, out, rmse_m)
    if says is None:
        assert not result.warnings
        assert not result.events
    else:
        assert len(result.warnings) == 1
        assert says in result.warnings[0]
        assert "0.02 m" in result.warnings[0]  # the fixes' own sigma, for the reader to compare
        assert result.events[0].kind == "health"


def _far_from_the_fixes(clock: object) -> list[str]:
    """The warnings of a run 13.7 m from RTK fixes, the LiDAR degenerate, no wheels, with `clock`."""
    import numpy as np

    from mrnc_eval.commands.slam import _add_gnss_disagreement
    from mrnc_eval.data import GnssSeries
    from mrnc_eval.results import RunResult
    from mrnc_eval.slam.output import SlamOutput

    n = 50
    gnss = GnssSeries(np.arange(n) * 0.2, np.zeros((n, 3)), np.zeros((n, 3)),
                      np.tile(np.diag([4e-4, 4e-4, 1e-3]), (n, 1, 1)), np.zeros(3))
    result = RunResult(kind="slam", log_path="x.mcap", log_id="x", extra={"inputs": {"lidar": "/points"}})
    out = SlamOutput(stamps=np.arange(10.0), poses=np.zeros((10, 4, 4)), kf_stamps=np.zeros(0),
                     kf_poses=np.zeros((0, 4, 4)), map_points=np.zeros((0, 3)), timing_ms={}, events=[], warnings=[],
                     n_sweeps=10, wall_s=0.0, degenerate=np.ones(10, bool))
    _add_gnss_disagreement(result, gnss, out, 13.7, clock=clock)  # type: ignore[arg-type]
    return result.warnings


@pytest.mark.parametrize(("shift", "says"), [
    ((18.1, 0.4), "18 s is GPS time against UTC"),  # a receiver stamping in GPS time
    ((2.0, 0.5), "look +2.00 s off the LiDAR's"),
    ((3.0, 12.0), "IMU dead reckoning"),  # negative control: no shift fits the fixes, the old diagnosis
    (None, "IMU dead reckoning"),
])
def test_gnss_stamps_off_the_lidar_clock_are_named(shift: tuple[float, float] | None, says: str) -> None:
    warnings = _far_from_the_fixes(lambda: shift)
    assert len(warnings) == 1
    assert says in warnings[0]
    assert ("GNSS stamps" in warnings[0]) == (shift is not None and shift[1] < 1.0)


@pytest.mark.parametrize("late_s", [18.0, -4.3, 0.0])
def test_the_gnss_clock_shift_is_found_on_a_loop(late_s: float) -> None:
    """Fixes of a 60 s weaving drive stamped late_s late: the shift that fits them back is late_s
    within the trajectory's 0.2 s sampling (0 is the negative control: fixes on time fit best
    unshifted). Not a circle: there a shift is a rotation, which the yaw alignment takes out."""
    import numpy as np

    from mrnc_eval.commands.slam import _gnss_clock_shift
    from mrnc_eval.data import GnssSeries, Trajectory

    t = np.arange(0.0, 60.0, 0.2)
    pos = np.c_[t, 5.0 * np.sin(0.2 * t), np.zeros(t.size)]
    yaw = np.arctan2(np.cos(0.2 * t), 1.0)  # the heading of the weave (dy/dx = cos(0.2 t))
    quat = np.c_[np.zeros((t.size, 2)), np.sin(yaw / 2), np.cos(yaw / 2)]
    est = Trajectory(t + 1000.0, pos, quat)
    gnss = GnssSeries(t + 1000.0 + late_s, np.zeros((t.size, 3)), pos + [3.0, -2.0, 0.0],
                      np.tile(np.eye(3) * 1e-4, (t.size, 1, 1)), np.zeros(3))
    found = _gnss_clock_shift(gnss, est, np.zeros(3), 0.05)
    assert found is not None
    assert found[0] == pytest.approx(late_s, abs=0.11)
    assert found[1] < 0.01
