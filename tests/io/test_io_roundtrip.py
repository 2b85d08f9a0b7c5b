"""Write small logs with the project's writer (rosbags' real writers) in all three
containers and read them back through the project's readers, asserting values."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval import geodesy
from mrnc_eval.data import ImuSeries, Trajectory, Twists, Waypoints
from mrnc_eval.errors import InputError
from mrnc_eval.io import open_log
from mrnc_eval.io.config import IoConfig
from mrnc_eval.io.writers import LogWriter
from mrnc_eval.slam.mapping_interval import MappingInterval

FORMATS = [("mcap", "log.mcap", "ros2-mcap"), ("db3", "log.db3", "ros2-sqlite3"), ("bag", "log.bag", "ros1"),
           ("mcap", "bagdir", "ros2-mcap")]
ORIGIN = np.array([47.3769, 8.5417, 408.0])
H, W = 8, 16


def _cloud(rng: np.random.Generator):
    xyz = rng.uniform(-20, 20, (H, W, 3)).astype(np.float32)
    xyz[0, :4] = 0.0  # no-return points, as ouster-ros publishes them
    t_ns = np.repeat((np.arange(W, dtype=np.uint32) * 6_250_000)[None, :], H, axis=0)  # 100 ms sweep
    rng_mm = (np.linalg.norm(xyz, axis=2) * 1000).astype(np.uint32)
    refl = rng.integers(0, 255, (H, W)).astype(np.uint16)
    return xyz, t_ns, rng_mm, refl, refl.astype(np.float32) * 2, refl


def write_sample(path: Path, fmt: str, *, duplicate_imu: bool = False) -> dict:
    rng = np.random.default_rng(1)
    t_imu = 100.0 + np.arange(50) * 0.01
    if duplicate_imu:
        t_imu = np.concatenate([t_imu, t_imu[10:12]])
    imu = ImuSeries(t_imu, rng.normal(size=(t_imu.size, 3)) + [0, 0, 9.81], rng.normal(size=(t_imu.size, 3)) * 0.1,
                    None, "os_imu")
    clouds = [_cloud(rng) for _ in range(3)]
    enu = np.array([[0.0, 0.0, 0.0], [10.0, 5.0, 1.0], [-3.0, 20.0, 0.5], [0.0, 0.0, 0.0]])
    lla = geodesy.enu_to_lla(enu, ORIGIN)
    gt = Trajectory(100.0 + np.arange(5) * 0.1, rng.normal(size=(5, 3)),
                    np.tile([0.0, 0.0, math.sin(0.2), math.cos(0.2)], (5, 1)))
    ext = np.eye(4)
    ext[:3, 3] = (0.5, 0.0, 1.2)
    with LogWriter(path, fmt) as w:
        w.write_tf_static([("base_link", "os_sensor", ext), ("os_sensor", "os_imu", np.eye(4))], 100.0)
        w.write_imu("/ouster/imu", imu)
        w.write_navsatfix("/gnss/fix", 100.0 + np.arange(4) * 0.1, lla, np.tile(np.eye(3) * 0.04, (4, 1, 1)),
                          np.array([0, 0, 0, -1]))
        w.write_joint_state("/wheel_speeds", [100.0, 100.1], ["left_wheel", "right_wheel"], [[1.0, 2.0], [1.5, 2.5]])
        w.write_joint_state("/pump_cmd", [100.0, 100.1], ["left_pump", "right_pump"],
                            [[900.0, 1100.0], [950.0, 1000.0]])
        w.write_odometry("/ground_truth", gt)
        w.write_path("/plan", Waypoints(np.array([[0.0, 0.0], [5.0, 0.0], [5.0, 5.0]]), frame_id="map"), 100.0)
        w.write_twist_stamped("/cmd_vel", Twists(np.array([100.0]), np.array([0.38]), np.array([0.07])))
        for k, c in enumerate(clouds):
            w.write_ouster_cloud("/ouster/points", 100.0 + 0.1 * k, *c)
    return {"imu": imu, "clouds": clouds, "enu": enu, "gt": gt, "ext": ext}


@pytest.mark.parametrize(("fmt", "name", "container"), FORMATS)
def test_round_trip_values(tmp_path: Path, fmt: str, name: str, container: str) -> None:
    src = write_sample(tmp_path / name, fmt)
    with open_log(tmp_path / name) as log:
        assert log.container == container
        assert log.roles["lidar"] == "/ouster/points"
        assert log.roles["imu"] == "/ouster/imu"
        assert log.roles["commands"] == "/pump_cmd"
        assert log.roles["wheel_speeds"] == "/wheel_speeds"
        assert log.roles["ground_truth"] == "/ground_truth"
        assert log.roles["gnss"] == "/gnss/fix"

        imu = log.imu()
        np.testing.assert_allclose(imu.stamps, src["imu"].stamps, atol=1e-9)
        np.testing.assert_allclose(imu.acc, src["imu"].acc)
        assert imu.orientation_xyzw is None  # 6-axis: orientation covariance -1

        sweeps = list(log.sweeps())
        assert [s.stamp for s in sweeps] == pytest.approx([100.0, 100.1, 100.2])
        xyz, t_ns, *_ = src["clouds"][1]
        valid = np.abs(xyz.reshape(-1, 3)).sum(axis=1) > 0
        assert len(sweeps[1]) == valid.sum() == H * W - 4
        np.testing.assert_array_equal(sweeps[1].points, xyz.reshape(-1, 3)[valid])
        np.testing.assert_allclose(sweeps[1].point_time, t_ns.reshape(-1)[valid] * 1e-9, atol=1e-9)
        np.testing.assert_array_equal(sweeps[1].ring, np.repeat(np.arange(H), W)[valid])

        gnss = log.gnss()
        assert gnss.n_no_fix == 1
        assert len(gnss.stamps) == 3
        np.testing.assert_allclose(gnss.enu, src["enu"][:3], atol=1e-6)

        ws = log.wheel_speeds(wheel_radius_m=0.5)
        np.testing.assert_allclose(ws.left, [0.5, 0.75])
        np.testing.assert_allclose(log.commands().right, [1100.0, 1000.0])
        gt = log.ground_truth()
        np.testing.assert_allclose(gt.positions, src["gt"].positions)
        np.testing.assert_allclose(gt.quat_xyzw, src["gt"].quat_xyzw)
        np.testing.assert_allclose(log.waypoints().xy, [[0, 0], [5, 0], [5, 5]])
        np.testing.assert_allclose(log.cmd_vel().omega, [0.07])
        np.testing.assert_allclose(log.transform("base_link", "os_imu"), src["ext"], atol=1e-12)
        np.testing.assert_allclose(log.transform("os_imu", "base_link"), np.linalg.inv(src["ext"]), atol=1e-12)


def test_duplicate_stamps_are_counted_and_dropped(tmp_path: Path) -> None:
    write_sample(tmp_path / "dup.mcap", "mcap", duplicate_imu=True)
    with open_log(tmp_path / "dup.mcap") as log:
        imu = log.imu()
        health = log.health("/ouster/imu")
    assert health.duplicates == 2
    assert np.all(np.diff(imu.stamps) > 0)
    assert imu.stamps.size == 50


def test_out_of_order_header_stamps_are_sorted_and_counted(tmp_path: Path) -> None:
    from mrnc_eval.io import messages as M

    header_stamps = [1.00, 1.01, 1.03, 1.02, 1.04]  # recorded in arrival order, one swapped
    w = LogWriter(tmp_path / "ooo.bag", "bag")
    conn = w._conn("/imu", "sensor_msgs/msg/Imu")
    for k, t in enumerate(header_stamps):
        msg = M.imu(w.ts, t, "imu", (0, 0, 9.81 + k), (0, 0, 0), None, ros1=True)
        w._writer.write(conn, int((1.0 + 0.01 * k) * 1e9), w._serialize(msg, "sensor_msgs/msg/Imu"))
    w.close()
    with open_log(tmp_path / "ooo.bag") as log:
        imu = log.imu()
        assert log.health("/imu").out_of_order == 1
    np.testing.assert_allclose(imu.stamps, sorted(header_stamps))
    np.testing.assert_allclose(imu.acc[:, 2], 9.81 + np.array([0, 1, 3, 2, 4]))


def test_role_override_by_topic(tmp_path: Path) -> None:
    write_sample(tmp_path / "a.mcap", "mcap")
    with open_log(tmp_path / "a.mcap", IoConfig(roles={"ground_truth": "/wheel_speeds"})) as log:
        assert log.roles["ground_truth"] == "/wheel_speeds"
    bad = IoConfig(roles={"imu": "/nope"})
    with pytest.raises(InputError, match="not in the log"), open_log(tmp_path / "a.mcap", bad) as log:
        log.roles  # noqa: B018


def test_enu_matches_closed_form() -> None:
    # 0.001 deg north at latitude phi: north = M * dphi with the meridian radius of curvature M.
    phi = math.radians(ORIGIN[0])
    m = geodesy.A * (1 - geodesy.E2) / (1 - geodesy.E2 * math.sin(phi) ** 2) ** 1.5
    north_and_up = np.array([[ORIGIN[0] + 1e-3, ORIGIN[1], ORIGIN[2]], [*ORIGIN[:2], ORIGIN[2] + 10]])
    enu = geodesy.lla_to_enu(north_and_up, ORIGIN)
    assert enu[0, 1] == pytest.approx((m + ORIGIN[2]) * math.radians(1e-3), rel=1e-6)
    assert abs(enu[0, 0]) < 1e-6
    np.testing.assert_allclose(enu[1], [0, 0, 10], atol=1e-6)
    back = geodesy.enu_to_lla(np.array([[1234.5, -678.9, 12.0]]), ORIGIN)
    np.testing.assert_allclose(geodesy.lla_to_enu(back, ORIGIN), [[1234.5, -678.9, 12.0]], atol=1e-6)


def test_same_input_gives_byte_identical_files(tmp_path: Path) -> None:
    for fmt, name in (("mcap", "x.mcap"), ("bag", "x.bag"), ("db3", "x.db3"), ("mcap", "xdir")):
        write_sample(tmp_path / "a" / name, fmt)
        write_sample(tmp_path / "b" / name, fmt)
        a, b = tmp_path / "a" / name, tmp_path / "b" / name
        files = sorted(p.name for p in a.iterdir()) if a.is_dir() else [""]
        for f in files:
            assert (a / f if f else a).read_bytes() == (b / f if f else b).read_bytes(), (name, f)


def test_failed_write_leaves_nothing(tmp_path: Path) -> None:
    with pytest.raises(RuntimeError), LogWriter(tmp_path / "x.mcap", "mcap") as w:  # noqa: PT012 - fail mid-write
        w.write_tf_static([("a", "b", np.eye(4))], 1.0)
        raise RuntimeError("simulated failure")
    assert list(tmp_path.iterdir()) == []


def test_sweeps_skipped_before_decoding_at_a_lower_mapping_rate(tmp_path: Path) -> None:
    write_sample(tmp_path / "a.mcap", "mcap")
    with open_log(tmp_path / "a.mcap") as log:
        kept = [s.stamp for s in log.sweeps(keep=MappingInterval(interval_s=0.15).take)]
    assert kept == pytest.approx([100.0, 100.2])


@pytest.mark.parametrize(("fmt", "name", "_kind"), FORMATS[:3])
def test_overview_pass_keeps_small_topics_so_series_do_not_reread_the_file(tmp_path: Path, fmt: str, name: str,
                                                                            _kind: str) -> None:
    """After the overview pass, IMU, GNSS, ground truth and TF come from memory (one pass over a
    compressed log instead of one per series) and equal what a reader without the cache returns."""
    write_sample(tmp_path / name, fmt)
    series = {}
    for budget in (1024.0, 0.0, 1e-3):  # default, off, and a budget the log exceeds (falls back to the file)
        with open_log(tmp_path / name, IoConfig(small_topic_cache_mb=budget)) as lg:
            assert lg.topics  # the overview pass
            passes: list[list[str]] = []

            def counting(topics, real=lg.source.iterate, seen=passes):
                seen.append(topics)
                return real(topics)

            lg.source.iterate = counting
            series[budget] = (lg.imu(), lg.gnss(), lg.ground_truth(), lg.transform("base_link", "os_imu"))
            reread = [t for t in passes if t != ["/ouster/points"]]
        assert (reread == []) == (budget == 1024.0), (budget, reread)
    (imu, gnss, gt, tf) = series[1024.0]
    for other in (series[0.0], series[1e-3]):
        np.testing.assert_array_equal(imu.stamps, other[0].stamps)
        np.testing.assert_array_equal(imu.gyro, other[0].gyro)
        np.testing.assert_array_equal(gnss.enu, other[1].enu)
        np.testing.assert_array_equal(gt.positions, other[2].positions)
        np.testing.assert_array_equal(tf, other[3])
