"""The field profile measured back from what it writes: each test estimates a configured
quantity from the data (Allan deviation, stamp offset, mount from the body's own points, noise
versus range, ...) and checks it against the configuration, with the ideal profile as the
negative control that must fail the same check."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mrnc_eval.config import Config
from mrnc_eval.io import open_log
from mrnc_eval.recording.recorder import LOG_EPOCH_S, SimRequest, mounts, simulate_log, transform
from mrnc_eval.sim.config import FieldImuConfig
from mrnc_eval.sim.gnss import STATUS_FIX, STATUS_GBAS_FIX, STATUS_SBAS_FIX, simulate_field_gnss
from mrnc_eval.sim.imu import imu_errors, vibration
from mrnc_eval.sim.lidar import FieldLidar, LidarSimulator
from mrnc_eval.sim.lidar_field import MovingBox, Puddles, range_sigma
from mrnc_eval.sim.scene import Terrain, build_scene
from mrnc_eval.sim.trajectory import GRAVITY_MPS2, BodyTrajectory

SMALL = dict(lidar="os0-32", columns=512)


def _field(cfg: Config | None = None, **world) -> Config:
    cfg = cfg or Config()
    f = cfg.sim.field
    return replace(cfg, sim=replace(cfg.sim, profile="field", field=replace(f, world=replace(f.world, **world))))


def _few_sweeps(cfg: Config, every: int) -> Config:
    return replace(cfg, sim=replace(cfg.sim, lidar=replace(cfg.sim.lidar, record_every=every)))


def allan_deviation(x: np.ndarray, rate_hz: float, taus_s: np.ndarray) -> np.ndarray:
    """Overlapping Allan deviation (IEEE 952) of rate samples x (N,) at the cluster times."""
    theta = np.r_[0.0, np.cumsum(x)] / rate_hz  # integrated signal
    out = []
    for tau in taus_s:
        m = round(tau * rate_hz)
        d = theta[2 * m:] - 2 * theta[m:-m] + theta[:-2 * m]
        out.append(np.sqrt(np.mean(d ** 2) / (2 * tau ** 2)))
    return np.asarray(out)


def _fit_white_and_walk(adev: np.ndarray, taus: np.ndarray) -> tuple[float, float]:
    """N (white density) and K (bias random walk) from sigma^2 = N^2 / tau + K^2 tau / 3 (least squares)."""
    a = np.c_[1.0 / taus, taus / 3.0]
    coef, *_ = np.linalg.lstsq(a / adev[:, None] ** 2, np.ones_like(taus), rcond=None)  # relative residuals
    return float(np.sqrt(coef[0])), float(np.sqrt(coef[1]))


def test_stationary_allan_deviation_matches_the_configured_noise() -> None:
    """Two hours standing still with the engine off (vibration 0): the white-noise density and the
    bias random walk fitted to the Allan deviation are the configured ones within 20 %."""
    cfg = replace(FieldImuConfig(), vibration_acc_rms=0.0, vibration_gyro_rms=0.0)
    rate = 100.0
    times = np.arange(0.0, 7200.0, 1.0 / rate)
    g_body = np.tile([0.1, -0.2, GRAVITY_MPS2], (times.size, 1))  # standing on a slight slope
    s = imu_errors(g_body, np.zeros_like(g_body), times, cfg, np.random.default_rng(3))
    assert 0 < times.size - s.times.size < 4 * cfg.drop_probability * times.size  # a few samples dropped
    taus = np.geomspace(0.05, 400.0, 14)
    for data, white, walk in ((s.acc, cfg.acc_noise_density, cfg.acc_bias_walk),
                              (s.gyro, cfg.gyro_noise_density, cfg.gyro_bias_walk)):
        adev = np.mean([allan_deviation(data[:, k], rate, taus) for k in range(3)], axis=0)
        n_fit, k_fit = _fit_white_and_walk(adev, taus)
        assert n_fit == pytest.approx(white, rel=0.2)
        assert k_fit == pytest.approx(walk, rel=0.2)
        assert adev[0] * np.sqrt(taus[0]) == pytest.approx(white, rel=0.2)  # the -1/2 slope at short tau
    # the turn-on bias is there and constant: the 2 h mean minus the truth is it (walk averages ~ K sqrt(T))
    np.testing.assert_allclose(s.gyro.mean(axis=0), s.gyro_turn_on_bias, atol=5 * cfg.gyro_bias_walk * 7200 ** 0.5)
    assert np.abs(s.gyro_turn_on_bias).max() > 0.2 * cfg.gyro_turn_on_bias


def test_negative_control_a_noise_model_of_twice_the_density_fails_the_allan_check() -> None:
    cfg = replace(FieldImuConfig(), vibration_acc_rms=0.0, vibration_gyro_rms=0.0)
    doubled = replace(cfg, gyro_noise_density=2 * cfg.gyro_noise_density)
    times = np.arange(0.0, 600.0, 0.01)
    s = imu_errors(np.zeros((times.size, 3)), np.zeros((times.size, 3)), times, doubled, np.random.default_rng(4))
    adev = allan_deviation(s.gyro[:, 2], 100.0, np.array([0.1]))
    assert adev[0] * np.sqrt(0.1) != pytest.approx(cfg.gyro_noise_density, rel=0.2)


def test_engine_vibration_lines_alias_where_a_100hz_sampler_puts_them() -> None:
    """30 and 60 Hz lines sampled at 100 Hz: peaks at 30 and 40 Hz (alias), total RMS as configured."""
    cfg = replace(FieldImuConfig(), acc_noise_density=0.0, acc_bias_walk=0.0, acc_turn_on_bias=0.0, acc_lsb=0.0)
    times = np.arange(0.0, 20.0, 0.01)
    v = vibration(times, cfg.vibration_hz, cfg.vibration_acc_rms, np.random.default_rng(0))
    assert v.std(axis=0) == pytest.approx(np.full(3, cfg.vibration_acc_rms), rel=0.05)
    spectrum = np.abs(np.fft.rfft(v[:, 0]))
    freqs = np.fft.rfftfreq(times.size, 0.01)
    assert sorted(freqs[np.argsort(spectrum)[-2:]].round(1).tolist()) == [30.0, 40.0]


def test_saturation_and_quantisation() -> None:
    cfg = FieldImuConfig()
    times = np.arange(0.0, 1.0, 0.01)
    big = np.tile([30.0, -25.0, 9.8], (times.size, 1))  # a jolt beyond +-2 g on x and y
    s = imu_errors(big, np.tile([0.0, 0.0, 6.0], (times.size, 1)), times, cfg, np.random.default_rng(1))
    assert np.all(s.acc[:, 0] == pytest.approx(cfg.acc_range, abs=cfg.acc_lsb))
    assert np.all(s.acc[:, 1] == pytest.approx(-cfg.acc_range, abs=cfg.acc_lsb))
    assert np.all(s.gyro[:, 2] == pytest.approx(cfg.gyro_range, abs=cfg.gyro_lsb))
    steps = s.acc[:, 2] / cfg.acc_lsb
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)


def _offset_from_gyro(log: Path, cfg: Config) -> float:
    """Stamp offset (s) of /ouster/imu against the true time, from its angular rate against the
    ground truth's (IMU axes of the true mount), by least squares over a grid of shifts."""
    with open_log(log) as lg:
        imu, gt = lg.imu(), lg.ground_truth()
        sensor_to_imu = lg.transform("os_sensor", "os_imu")
    r_bi = (mounts(cfg)[1] @ sensor_to_imu)[:3, :3]
    rot = Rotation.from_quat(gt.quat_xyzw)
    w_body = (rot[:-1].inv() * rot[1:]).as_rotvec() / np.diff(gt.stamps)[:, None]  # base_link rate, mid-steps
    w_imu = w_body @ r_bi
    t_mid = 0.5 * (gt.stamps[:-1] + gt.stamps[1:])
    inside = (imu.stamps > t_mid[0] + 0.05) & (imu.stamps < t_mid[-1] - 0.05)
    shifts = np.arange(-0.02, 0.02, 1e-4)
    cost = []
    for tau in shifts:
        ref = np.stack([np.interp(imu.stamps[inside] - tau, t_mid, w_imu[:, k]) for k in range(3)], axis=1)
        d = imu.gyro[inside] - ref
        cost.append(np.sum((d - d.mean(axis=0)) ** 2))  # the constant bias does not count
    return float(shifts[int(np.argmin(cost))])


@pytest.fixture(scope="module")
def field_log(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Config]:
    """A 12 s field log over stones (they make the angular rate sharp enough to time), 1 kHz
    ground truth, one sweep in ten."""
    cfg = _few_sweeps(_field(stones_per_m=2.0), 10)
    cfg = replace(cfg, sim=replace(cfg.sim, ground_truth_rate_hz=1000.0))
    log = simulate_log(tmp_path_factory.mktemp("field") / "f.mcap", cfg,
                       SimRequest(scene="yard", path="circle", duration_s=12.0, seed=6, **SMALL))
    return log, cfg


def test_clock_offset_is_in_the_written_imu_stamps(field_log: tuple[Path, Config]) -> None:
    log, cfg = field_log
    clock = cfg.sim.field.clock
    assert _offset_from_gyro(log, cfg) == pytest.approx(clock.imu_offset_s, abs=1e-3)
    with open_log(log) as lg:
        sweeps = [s.stamp for s in lg.sweeps()]
        gnss = lg.gnss()
    # LiDAR stamps keep the true sweep starts (to the jitter); GNSS is stamped late by the latency
    start = np.round((np.asarray(sweeps) - LOG_EPOCH_S) / 0.1) * 0.1 + LOG_EPOCH_S
    assert np.abs(np.asarray(sweeps) - start).max() < 5 * clock.lidar_jitter_s + 1e-6
    late = np.mod(gnss.stamps - LOG_EPOCH_S, 1.0 / cfg.sim.gnss.rate_hz)
    assert np.median(late) == pytest.approx(clock.gnss_latency_s, abs=3 * clock.host_jitter_s)


def test_negative_control_the_ideal_log_has_no_clock_offset(tmp_path: Path) -> None:
    cfg = _few_sweeps(Config(), 1000)
    cfg = replace(cfg, sim=replace(cfg.sim, ground_truth_rate_hz=1000.0))
    log = simulate_log(tmp_path / "i.mcap", cfg, SimRequest(scene="field", path="circle", duration_s=12.0, seed=6,
                                                            **SMALL))
    assert abs(_offset_from_gyro(log, cfg)) < 1e-3


def _body_top_plane(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Unit normal (pointing up) and distance below the sensor of the plane through the points,
    fitted twice: the second time without residuals above 3 cm (mixed pixels, outliers)."""
    keep = np.ones(len(points), bool)
    for _ in range(2):
        c = points[keep].mean(axis=0)
        _, _, vt = np.linalg.svd(points[keep] - c)
        n = vt[2] if vt[2, 2] > 0 else -vt[2]
        keep = np.abs((points - c) @ n) < 0.03
    return n, float(-(c @ n))


@pytest.mark.parametrize("profile", ["field", "ideal"])
def test_tf_static_differs_from_the_mount_the_body_points_show(tmp_path: Path, profile: str) -> None:
    """The body's top face is z = top in base_link; its plane in the cloud (os_sensor) gives the
    true mount's roll, pitch and height. /tf_static keeps the nominal mount, so the two differ by
    the configured calibration error (field) or not at all (ideal, the negative control)."""
    cfg = replace(Config(), sim=replace(Config().sim, lidar=replace(Config().sim.lidar, self_occlusion=True)))
    cfg = _field(cfg, moving_object="none") if profile == "field" else cfg
    log = simulate_log(tmp_path / "b.mcap", cfg, SimRequest(scene="yard", path="circle", duration_s=1.0, seed=1,
                                                            **SMALL))
    with open_log(log) as lg:
        written = lg.transform("base_link", "os_sensor")
        sweep = next(iter(lg.sweeps()))
    np.testing.assert_allclose(written, transform(cfg.sim.lidar.mount_xyz_m), atol=1e-9)  # the nominal mount
    top = cfg.robot.height_m - 0.6
    pts = sweep.points.astype(float)
    below = written[2, 3] - top  # where the written mount says the top face is
    on_top = (np.abs(pts[:, 2] + below) < 0.15) & (pts[:, 0] < 0.7) & (pts[:, 0] > -3.1) & (np.abs(pts[:, 1]) < 0.9)
    assert on_top.sum() > 300
    n, dist = _body_top_plane(pts[on_top])
    cal = cfg.sim.field.calibration
    err = Rotation.from_euler("xyz", cal.lidar_rpy_error_deg, degrees=True)
    expected_n = err.inv().apply([0.0, 0.0, 1.0])  # base_link up, seen in the true sensor axes
    expected_dist = below + cal.lidar_xyz_error_m[2]
    found = (np.degrees(np.arccos(np.clip(n @ expected_n, -1, 1))) < 0.05) and abs(dist - expected_dist) < 0.004
    assert found == (profile == "field")
    if profile == "ideal":
        np.testing.assert_allclose(n, [0.0, 0.0, 1.0], atol=1e-3)  # 0.06 deg; the field error is 0.5 deg
        assert dist == pytest.approx(below, abs=0.002)


def test_field_body_returns_at_fixed_pixels_inside_the_slam_crop_box(tmp_path: Path) -> None:
    cfg = _field(moving_object="none", stones_per_m=0.0)
    log = simulate_log(tmp_path / "body.mcap", cfg, SimRequest(scene="yard", path="circle", duration_s=3.0, seed=1,
                                                               **SMALL))
    box = np.asarray(cfg.slam.features.body_crop_box_m)
    pixels = []
    with open_log(log) as lg:
        sweeps = list(lg.sweeps())[5:25:6]
    for s in sweeps:
        inside = np.all((s.points >= box[:3]) & (s.points <= box[3:]), axis=1)
        assert inside.sum() > 300
        pixels.append(set(zip(s.ring[inside].tolist(), s.column[inside].tolist(), strict=True)))
    common = set.intersection(*pixels)
    # outliers, dark dropouts at grazing incidence and mixed edge pixels change a few per sweep
    assert all(len(common) > 0.9 * len(p) for p in pixels)
    ideal = simulate_log(tmp_path / "ideal.mcap", Config(), SimRequest(scene="yard", path="circle", duration_s=1.0,
                                                                       seed=1, **SMALL))
    with open_log(ideal) as lg:
        s = next(iter(lg.sweeps()))
    assert np.all(np.any((s.points < box[:3]) | (s.points > box[3:]), axis=1))  # no body by default when ideal


def _still(duration_s: float) -> BodyTrajectory:
    t = np.linspace(0.0, duration_s, 50)
    return BodyTrajectory(t, np.zeros_like(t), np.zeros_like(t), np.zeros_like(t), Terrain(0.0, 0.0, 0))


def test_moving_object_crosses_the_cloud() -> None:
    """A person walking at 1.4 m/s along y = 6 m in front of a still machine: its returns are
    where the object is at each sweep's time and move with it."""
    cfg = replace(Config().sim.lidar, beams=32, columns=512)
    scene = build_scene("field", seed=0, amplitude_m=0.0, roughness_m=0.0)
    person = MovingBox(np.array([4.0, -10.0]), np.array([0.0, 1.0]), 20.0, 1.4, 0.0, (0.4, 0.6, 1.8), 0.3)
    fcfg = replace(Config().sim.field.lidar, outlier_fraction=0.0)
    field = FieldLidar(fcfg, Puddles(np.zeros((0, 2)), np.zeros(0)), person, np.random.default_rng(0))
    lidar = LidarSimulator(scene, cfg, transform((1.2, 0.0, 1.9)), np.random.default_rng(0), None, field)
    traj = _still(10.0)
    centres = []
    for t in (5.0, 7.0, 9.0):
        s = lidar.sweep(traj, t)
        p = s.xyz.reshape(-1, 3).astype(float)
        p = p[np.any(p != 0, axis=1)] + (1.2, 0.0, 1.9)  # base_link = map here
        above = p[p[:, 2] > 0.3]  # not the ground
        assert len(above) > 20
        centres.append(above[:, :2].mean(axis=0))
        true = person.centre_xy(np.array([t + 0.05]))[0]
        assert np.linalg.norm(centres[-1] - true) < 0.5
    np.testing.assert_allclose(np.diff(np.asarray(centres)[:, 1]), 2.8, atol=0.3)  # 1.4 m/s over 2 s


def test_range_noise_grows_with_range_and_falls_with_reflectivity() -> None:
    cfg = Config().sim.field.lidar
    r = np.array([2.0, 10.0, 35.0, 35.0])
    sig = range_sigma(r, np.array([0.5, 0.5, 0.1, 0.5]), np.ones(4), cfg)
    assert sig[0] < sig[1] < sig[2]
    assert sig[3] < sig[2]
    assert sig[2] == pytest.approx(np.hypot(cfg.range_noise_floor_m, cfg.range_noise_ref_m), rel=1e-9)
    # measured: a wall straight ahead at 5 m and at 30 m, normal incidence, many sweeps
    scene_cfg = replace(Config().sim.lidar, beams=32, columns=512)
    spreads = {}
    for dist in (5.0, 30.0):
        from mrnc_eval.sim.scene import Scene, box_mesh

        scene = Scene("wall", Terrain(0.0, 0.0, 0))
        scene.add(*box_mesh(1.2 + dist + 0.5, 0.0, -5.0, 1.0, 40.0, 20.0), 0.1)  # a dark (10 %) wall
        field = FieldLidar(replace(cfg, outlier_fraction=0.0), Puddles(np.zeros((0, 2)), np.zeros(0)), None,
                           np.random.default_rng(1))
        lidar = LidarSimulator(scene, scene_cfg, transform((1.2, 0.0, 1.9)), np.random.default_rng(1), None, field)
        residuals = []
        for t in np.arange(0.0, 1.0, 0.1):
            s = lidar.sweep(_still(2.0), float(t))
            x = s.xyz[..., 0].astype(float)
            ahead = (s.range_mm > 0) & (np.abs(s.xyz[..., 1]) < 0.1 * x) & (np.abs(s.xyz[..., 2]) < 0.06 * x)
            residuals.append(x[ahead] - dist)
        spreads[dist] = float(np.std(np.concatenate(residuals)))
    expected = range_sigma(np.array([5.0, 30.0]), np.full(2, 0.1), np.ones(2), cfg)
    assert spreads[30.0] > 1.5 * spreads[5.0]
    np.testing.assert_allclose([spreads[5.0], spreads[30.0]], expected, rtol=0.25)


def test_gnss_fix_type_and_multipath_follow_the_distance_to_structures() -> None:
    """Driving along x past a wall at x = 50 m: RTK fixed far away, float, then single point
    close to it, with noise and multipath jumps only near it."""
    cfg = Config().sim
    f = replace(cfg.field.gnss, multipath_rate_hz=0.5)
    t = np.linspace(0.0, 1000.0, 101)
    traj = BodyTrajectory(t, 0.1 * t, np.zeros_like(t), np.zeros_like(t), Terrain(0.0, 0.0, 0))
    wall = np.c_[np.full(50, 50.0), np.linspace(-1.0, 1.0, 50)]
    times = np.arange(0.0, 1000.0, 0.2)
    fixes = simulate_field_gnss(traj, times, np.eye(4), replace(cfg.gnss, dropout_probability=0.0), f, wall,
                                np.random.default_rng(2))
    x = fixes.true_enu[:, 0]
    near = np.abs(x - 50.0)
    assert np.all(fixes.status[near > f.float_within_m + 0.1] == STATUS_GBAS_FIX)
    assert np.all(fixes.status[near < f.single_within_m - 0.1] == STATUS_FIX)
    mid = (near > f.single_within_m + 0.1) & (near < f.float_within_m - 0.1)
    assert np.all(fixes.status[mid] == STATUS_SBAS_FIX)
    from mrnc_eval.geodesy import lla_to_enu

    err = lla_to_enu(fixes.lla, np.asarray(cfg.gnss.origin_lla, float)) - fixes.true_enu
    far = near > f.float_within_m + 1.0  # a jump started at the edge lasts <= 8 s = 0.8 m at 0.1 m/s
    assert np.std(err[far, 0]) == pytest.approx(f.sigma_fixed_m, rel=0.2)
    np.testing.assert_allclose(fixes.covariance[far, 0, 0], f.sigma_fixed_m ** 2)
    assert np.abs(err[far, :2]).max() < 6 * f.sigma_fixed_m  # no multipath in the open
    close = near < f.single_within_m - 0.1
    assert np.abs(err[close | mid, :2]).max() > f.multipath_jump_m[0]  # jumps near the wall
