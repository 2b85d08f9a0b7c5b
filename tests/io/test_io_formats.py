"""Container and message-layout variants: Velodyne/`timestamp` clouds written with rosbags
directly, split and bz2 ROS 1 bags, plain (ROS 1 encoded) MCAP through the mcap library,
sqlite3 bags without stored type definitions, unknown types, wrong-type topics, and ENU
against an independent rotation-based computation."""

from __future__ import annotations

import math
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval import geodesy
from mrnc_eval.data import ImuSeries
from mrnc_eval.errors import InputError
from mrnc_eval.io import open_log
from mrnc_eval.io.typestore import typestore_for
from mrnc_eval.io.writers import LogWriter
from tests.io.test_io_roundtrip import write_sample

# ------------------------------------------------------------------ custom clouds


def _write_cloud_bag(path: Path, fields: list[tuple[str, int, int]], point_step: int, data: np.ndarray,
                     stamp: float, *, height: int = 1) -> None:
    """One PointCloud2 of arbitrary layout in a ROS 2 MCAP bag, via rosbags' writer only."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    ts = typestore_for(ros1=False)
    T = ts.types
    pf = [T["sensor_msgs/msg/PointField"](name=n, offset=o, datatype=d, count=1) for n, o, d in fields]
    n = data.size // point_step
    sec = int(stamp)
    msg = T["sensor_msgs/msg/PointCloud2"](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
            sec=sec, nanosec=round((stamp - sec) * 1e9)), frame_id="velodyne"),
        height=height, width=n // height, fields=pf, is_bigendian=False, point_step=point_step,
        row_step=point_step * (n // height), data=data, is_dense=False)
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection("/points_raw", "sensor_msgs/msg/PointCloud2", typestore=ts)
        w.write(conn, round(stamp * 1e9), ts.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2"))


def test_velodyne_cloud_decoded_by_field_name(tmp_path: Path) -> None:
    # Velodyne driver layout: x y z intensity f4, ring u2, time f4 (s relative to the stamp)
    dtype = np.dtype({"names": ["x", "y", "z", "intensity", "ring", "time"],
                      "formats": ["<f4", "<f4", "<f4", "<f4", "<u2", "<f4"],
                      "offsets": [0, 4, 8, 12, 16, 18], "itemsize": 22})
    rng = np.random.default_rng(3)
    pts = np.zeros(200, dtype=dtype)
    for k in "xyz":
        pts[k] = rng.uniform(-30, 30, 200)
    pts["ring"] = np.arange(200) % 16
    pts["time"] = np.linspace(-0.1, 0.0, 200)  # VLP-16 stamps at the sweep end: negative offsets
    pts["intensity"] = rng.uniform(0, 100, 200)
    pts["x"][[5, 17]] = np.nan  # no-return points
    fields = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 12, 7), ("ring", 16, 4), ("time", 18, 7)]
    _write_cloud_bag(tmp_path / "velo", fields, 22, pts.view(np.uint8), 50.25)
    with open_log(tmp_path / "velo") as log:
        assert log.roles["lidar"] == "/points_raw"
        (sweep,) = list(log.sweeps())
    keep = np.isfinite(pts["x"])
    assert sweep.stamp == pytest.approx(50.25)
    assert len(sweep) == 198
    assert sweep.frame_id == "velodyne"
    np.testing.assert_array_equal(sweep.points[:, 0], pts["x"][keep])
    np.testing.assert_array_equal(sweep.ring, pts["ring"][keep])
    np.testing.assert_allclose(sweep.point_time, pts["time"][keep], atol=1e-7)
    np.testing.assert_allclose(sweep.intensity, pts["intensity"][keep])


@pytest.mark.parametrize("absolute", [True, False])
def test_timestamp_f64_absolute_or_relative_and_ring_u8(tmp_path: Path, absolute: bool) -> None:
    dtype = np.dtype({"names": ["timestamp", "x", "y", "z", "ring"], "formats": ["<f8", "<f4", "<f4", "<f4", "u1"],
                      "offsets": [0, 8, 12, 16, 20], "itemsize": 24})
    stamp = 1_700_000_000.5
    pts = np.zeros(64, dtype=dtype)
    pts["x"], pts["y"], pts["z"] = 1.0, np.arange(64), 2.0
    rel = np.arange(64) * 1e-3
    pts["timestamp"] = stamp + rel if absolute else rel
    pts["ring"] = np.arange(64) % 32
    pts["x"][0] = pts["y"][0] = pts["z"][0] = 0.0  # no return
    fields = [("timestamp", 0, 8), ("x", 8, 7), ("y", 12, 7), ("z", 16, 7), ("ring", 20, 2)]
    _write_cloud_bag(tmp_path / "hesai", fields, 24, pts.view(np.uint8), stamp)
    with open_log(tmp_path / "hesai") as log:
        (sweep,) = list(log.sweeps())
    np.testing.assert_allclose(sweep.point_time, rel[1:], atol=1e-6)  # s since the sweep start
    np.testing.assert_array_equal(sweep.ring, pts["ring"][1:])


def test_cloud_without_time_field_has_no_point_time(tmp_path: Path) -> None:
    pts = np.arange(30, dtype="<f4").reshape(10, 3) + 1
    _write_cloud_bag(tmp_path / "xyz", [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)], 12, pts.view(np.uint8).reshape(-1), 1.0)
    with open_log(tmp_path / "xyz") as log:
        (sweep,) = list(log.sweeps())
    assert sweep.point_time is None
    assert sweep.ring is None
    np.testing.assert_array_equal(sweep.points, pts)


# ------------------------------------------------------------------ ROS 1 variants


def _imu(t0: float, n: int) -> ImuSeries:
    t = t0 + np.arange(n) * 0.01
    return ImuSeries(t, np.column_stack([t, -t, np.full(n, 9.81)]), np.zeros((n, 3)), None, "imu")


def test_split_ros1_bags_as_list_and_glob(tmp_path: Path) -> None:
    for k in range(3):
        with LogWriter(tmp_path / f"run_{k}.bag", "bag") as w:
            w.write_imu("/imu", _imu(10.0 + k, 100))
    with open_log([tmp_path / "run_2.bag", tmp_path / "run_0.bag", tmp_path / "run_1.bag"]) as log:
        imu = log.imu()
        assert log.container == "ros1"
        assert log.topics[0].count == 300
    np.testing.assert_allclose(imu.stamps, 10.0 + np.arange(300) * 0.01, atol=1e-9)  # merged and sorted
    np.testing.assert_allclose(imu.acc[:, 0], imu.stamps)
    with open_log(str(tmp_path / "run_*.bag")) as log:
        assert log.duration_s == pytest.approx(2.99)
    with pytest.raises(InputError, match="no file matches"):
        open_log(str(tmp_path / "nothing_*.bag"))


@pytest.mark.parametrize("compression", ["bz2", "lz4", None])
def test_ros1_chunk_compression(tmp_path: Path, compression: str | None) -> None:
    with LogWriter(tmp_path / "c.bag", "bag", ros1_compression=compression) as w:
        w.write_imu("/imu", _imu(5.0, 500))
    raw = (tmp_path / "c.bag").read_bytes()
    assert (b"compression=" + (compression or "none").encode()) in raw  # really that chunk format
    with open_log(tmp_path / "c.bag") as log:
        np.testing.assert_allclose(log.imu().acc[:, 1], -(5.0 + np.arange(500) * 0.01))


def test_plain_mcap_with_ros1_encoded_channels(tmp_path: Path) -> None:
    """An MCAP written by a ROS 1 recorder (profile ros1) goes through the mcap library."""
    from mcap.writer import Writer

    from mrnc_eval.io import messages as M

    ts = typestore_for(ros1=True)
    msgdef, _md5 = ts.generate_msgdef("sensor_msgs/msg/Imu")
    p = tmp_path / "ros1.mcap"
    with p.open("wb") as fh:
        w = Writer(fh)
        w.start(profile="ros1", library="test")
        sid = w.register_schema(name="sensor_msgs/Imu", encoding="ros1msg", data=msgdef.encode())
        cid = w.register_channel(topic="/imu", message_encoding="ros1", schema_id=sid)
        for k in range(20):
            t = 3.0 + 0.01 * k
            msg = M.imu(ts, t, "imu", (k, 0, 9.81), (0, 0, 0.1 * k), None, ros1=True, seq=k)
            w.add_message(channel_id=cid, log_time=round(t * 1e9), publish_time=round(t * 1e9),
                          data=bytes(ts.serialize_ros1(msg, "sensor_msgs/msg/Imu")))
        w.finish()
    with open_log(p) as log:
        assert log.container == "mcap"
        assert log.roles["imu"] == "/imu"
        assert log.topics[0].msgtype == "sensor_msgs/msg/Imu"
        assert log.topics[0].count == 20
        imu = log.imu()
    np.testing.assert_allclose(imu.stamps, 3.0 + 0.01 * np.arange(20), atol=1e-9)
    np.testing.assert_allclose(imu.gyro[:, 2], 0.1 * np.arange(20))


# ------------------------------------------------------------------ types


def test_sqlite3_bag_without_type_definitions_uses_humble_types(tmp_path: Path) -> None:
    """ROS 2 Humble's recorder stores no message definitions in .db3 files."""
    write_sample(tmp_path / "h.db3", "db3")
    with sqlite3.connect(tmp_path / "h.db3") as db:
        tables = {r[0] for r in db.execute("select name from sqlite_master where type='table'")}
        assert "message_definitions" in tables
        db.execute("delete from message_definitions")
    with open_log(tmp_path / "h.db3") as log:
        assert log.imu().stamps.size == 50
        assert len(list(log.sweeps())) == 3


def test_unknown_message_type_is_listed_and_refused_when_read(tmp_path: Path) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_types_from_msg

    ts = typestore_for(ros1=False)
    ts.register(get_types_from_msg("float64 pressure_bar\nuint8 mode", "acme_msgs/msg/PumpState"))
    with Writer(tmp_path / "u", version=8, storage_plugin=StoragePlugin.SQLITE3) as w:
        conn = w.add_connection("/pump_state", "acme_msgs/msg/PumpState", typestore=ts)
        msg = ts.types["acme_msgs/msg/PumpState"](pressure_bar=180.0, mode=2)
        w.write(conn, 1_000_000_000, ts.serialize_cdr(msg, "acme_msgs/msg/PumpState"))
    # the definition was stored: the custom type decodes
    db3 = tmp_path / "u" / "u.db3"  # the single file, opened on its own
    with open_log(db3) as log:
        assert log.topics[0].problem is None
        assert log.topics[0].count == 1
    # a recorder that stored no definition: the type is unknown, listed, refused by name when read
    with sqlite3.connect(db3) as db:
        db.execute("delete from message_definitions")
    with open_log(db3) as log:
        (info,) = log.topics
        assert info.msgtype == "acme_msgs/msg/PumpState"
        assert "unknown message type" in info.problem
        with pytest.raises(InputError, match=r"\[/pump_state\]: unknown message type acme_msgs/msg/PumpState"):
            log.trajectory("/pump_state")


def test_typed_reader_on_a_topic_of_another_type(tmp_path: Path) -> None:
    write_sample(tmp_path / "a.bag", "bag")
    with open_log(tmp_path / "a.bag") as log:
        expected = r"\[/gnss/fix\]: expected sensor_msgs/msg/Imu, got sensor_msgs/msg/NavSatFix"
        with pytest.raises(InputError, match=expected):
            log.imu("/gnss/fix")
        with pytest.raises(InputError, match=r"\[/ouster/imu\].*PointCloud2"):
            next(log.sweeps("/ouster/imu"))
        with pytest.raises(InputError, match=r"\[/cmd_vel\].*not a pose type"):
            log.trajectory("/cmd_vel")


def test_plain_twist_uses_record_time(tmp_path: Path) -> None:
    from mrnc_eval.io import messages as M

    w = LogWriter(tmp_path / "tw.mcap", "mcap")
    T = w.ts.types
    conn = w._conn("/cmd_vel", "geometry_msgs/msg/Twist")
    for k in range(3):
        msg = T["geometry_msgs/msg/Twist"](linear=M.vector3(w.ts, (0.1 * k, 0, 0)), angular=M.vector3(w.ts, (0, 0, -k)))
        w._writer.write(conn, (7 + k) * 10**9, w._serialize(msg, "geometry_msgs/msg/Twist"))
    w.close()
    with open_log(tmp_path / "tw.mcap") as log:
        tw = log.cmd_vel()
    np.testing.assert_allclose(tw.stamps, [7, 8, 9])
    np.testing.assert_allclose(tw.v, [0, 0.1, 0.2])
    np.testing.assert_allclose(tw.omega, [0, -1, -2])


# ------------------------------------------------------------------ ENU


def test_enu_against_independent_rotation_composition() -> None:
    """ENU axes = ECEF rotated by Rz(lon + 90 deg) then Rx(90 deg - lat) (scipy), ECEF from the
    geocentric formula with the prime-vertical radius written out independently."""
    from scipy.spatial.transform import Rotation

    origin = np.array([-33.8688, 151.2093, 58.0])
    rng = np.random.default_rng(11)
    lla = origin + np.column_stack([rng.uniform(-0.02, 0.02, 50), rng.uniform(-0.02, 0.02, 50),
                                    rng.uniform(-30, 30, 50)])
    a, b = 6378137.0, 6356752.314245179  # WGS-84 semi-axes, m

    def ecef(lat_deg, lon_deg, h):
        lat, lon = np.radians(lat_deg), np.radians(lon_deg)
        n = a**2 / np.sqrt(a**2 * np.cos(lat) ** 2 + b**2 * np.sin(lat) ** 2)
        return np.column_stack([(n + h) * np.cos(lat) * np.cos(lon), (n + h) * np.cos(lat) * np.sin(lon),
                                (b**2 / a**2 * n + h) * np.sin(lat)])

    enu_from_ecef = Rotation.from_euler("ZX", [origin[1] + 90.0, 90.0 - origin[0]], degrees=True).inv()
    expected = enu_from_ecef.apply(ecef(*lla.T) - ecef(*origin[:, None]))
    got = geodesy.lla_to_enu(lla, origin)
    np.testing.assert_allclose(got, expected, atol=1e-6)
    assert np.abs(got[:, :2]).max() > 1000  # kilometres from the origin, not a trivial case
    assert math.isclose(float(np.linalg.norm(got[0])), float(np.linalg.norm(expected[0])), rel_tol=1e-12)


def test_gnss_without_covariance_gets_the_configured_variance(tmp_path: Path) -> None:
    from mrnc_eval.io.config import IoConfig

    origin = np.array([47.0, 8.0, 400.0])
    lla = geodesy.enu_to_lla(np.array([[0.0, 0.0, 0.0], [3.0, 4.0, 0.0]]), origin)
    cov = np.stack([np.zeros((3, 3)), np.diag([0.25, 0.25, 1.0])])  # unknown, then known
    with LogWriter(tmp_path / "g.mcap", "mcap") as w:
        w.write_navsatfix("/fix", [1.0, 2.0], lla, cov, [0, 2])
    with open_log(tmp_path / "g.mcap", IoConfig(gnss_unknown_variance_m2=(9.0, 9.0, 25.0))) as log:
        gnss = log.gnss()
        notes = log.health("/fix").notes
    np.testing.assert_allclose(gnss.covariance[0], np.diag([9.0, 9.0, 25.0]))
    np.testing.assert_allclose(gnss.covariance[1], np.diag([0.25, 0.25, 1.0]))
    np.testing.assert_allclose(gnss.enu[1], [3.0, 4.0, 0.0], atol=1e-6)
    assert notes
    assert "1 fix(es) without covariance" in notes[0]


def test_pose_stamped_and_tf_trajectories(tmp_path: Path) -> None:
    from scipy.spatial.transform import Rotation

    from mrnc_eval.io import messages as M

    w = LogWriter(tmp_path / "p.bag", "bag")
    yaw = np.array([0.0, 0.3, 0.6])
    xyz = np.array([[0.0, 0.0, 0.0], [1.0, 0.5, 0.1], [2.0, 1.5, 0.2]])
    q = Rotation.from_euler("z", yaw[:, None]).as_quat()
    for k in range(3):
        t = 5.0 + 0.5 * k
        ps = w.ts.types["geometry_msgs/msg/PoseStamped"](header=M.header(w.ts, t, "map", True, k),
                                                         pose=M.pose(w.ts, xyz[k], q[k]))
        w._queue("/slam/pose", "geometry_msgs/msg/PoseStamped", t, ps)
        mat = np.eye(4)
        mat[:3, :3], mat[:3, 3] = Rotation.from_quat(q[k]).as_matrix(), xyz[k]
        other = np.eye(4)
        tf = M.tf_message(w.ts, t, [("odom", "base_link", mat), ("map", "odom", other)], True)
        w._queue("/tf", "tf2_msgs/msg/TFMessage", t, tf)
    w.write_tf_static([("base_link", "os_sensor", np.eye(4)), ("os_sensor_mount", "os_lidar", np.eye(4))], 5.0)
    w.close()
    with open_log(tmp_path / "p.bag") as log:
        assert log.roles["tf"] == "/tf"
        assert log.roles["tf_static"] == "/tf_static"
        pose = log.trajectory("/slam/pose")
        tf = log.trajectory("/tf:odom.base_link")
        chained = log.trajectory("/tf:map.base_link")  # through odom (map -> odom is the identity), as tf2
        with pytest.raises(InputError, match=r"\[/tf\]: no TF chain from 'map' to 'os_lidar'"):
            log.trajectory("/tf:map.os_lidar")
    for traj in (pose, tf, chained):
        np.testing.assert_allclose(traj.stamps, [5.0, 5.5, 6.0])
        np.testing.assert_allclose(traj.positions, xyz, atol=1e-12)
        np.testing.assert_allclose(np.abs(np.sum(traj.quat_xyzw * q, axis=1)), 1.0, atol=1e-12)
    assert pose.frame_id == "map"
    assert tf.frame_id == "odom"
    assert tf.child_frame_id == "base_link"


@pytest.mark.parametrize("compression", ["LZ4", "ZSTD", "NONE"])
def test_ros2_mcap_chunk_compression(tmp_path: Path, compression: str) -> None:
    """ROS 2 MCAP written by the mcap library itself (not rosbags), with each chunk compression."""
    from mcap.writer import CompressionType, Writer

    from mrnc_eval.io import messages as M

    ts = typestore_for(ros1=False)
    msgdef, _ = ts.generate_msgdef("sensor_msgs/msg/Imu", ros_version=2)
    p = tmp_path / "c.mcap"
    with p.open("wb") as fh:
        w = Writer(fh, compression=getattr(CompressionType, compression))
        w.start(profile="ros2", library="test")
        sid = w.register_schema(name="sensor_msgs/msg/Imu", encoding="ros2msg", data=msgdef.encode())
        cid = w.register_channel(topic="/imu", message_encoding="cdr", schema_id=sid)
        for k in range(200):
            t = 3.0 + 0.01 * k
            msg = M.imu(ts, t, "imu", (k, 0, 9.81), (0, 0, 0.1 * k), None, ros1=False)
            w.add_message(channel_id=cid, log_time=round(t * 1e9), publish_time=round(t * 1e9),
                          data=bytes(ts.serialize_cdr(msg, "sensor_msgs/msg/Imu")))
        w.finish()
    with open_log(p) as log:
        assert log.container == "ros2-mcap"
        imu = log.imu()
    np.testing.assert_allclose(imu.acc[:, 0], np.arange(200))
    np.testing.assert_allclose(imu.stamps, 3.0 + 0.01 * np.arange(200), atol=1e-9)


def test_bag_directory_given_by_its_metadata_file(tmp_path: Path) -> None:
    write_sample(tmp_path / "run", "db3")
    with open_log(tmp_path / "run" / "metadata.yaml") as log:
        assert log.container == "ros2-sqlite3"
        assert log.path == tmp_path / "run"
        assert log.imu().stamps.size == 50


@pytest.mark.parametrize(("fmt", "name"), [("mcap", "i.mcap"), ("db3", "i.db3"), ("bag", "i.bag")])
def test_batched_imu_decoding_equals_per_message(tmp_path: Path, fmt: str, name: str) -> None:
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(5)
    n = 300
    t = 50.0 + np.arange(n) * 0.005 + rng.uniform(0, 1e-4, n)
    q = Rotation.random(n, random_state=3).as_quat()
    nine_axis = ImuSeries(t, rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), q, "imu_link_with_a_long_name")
    with LogWriter(tmp_path / name, fmt) as w:
        w.write_imu("/imu9", nine_axis)
        w.write_imu("/imu6", _imu(50.0, 120))
        for k, frame in enumerate(["a", "bb", "ccc"]):  # varying frame ids: the per-message path
            w.write_imu("/mixed", ImuSeries(np.array([60.0 + k]), np.full((1, 3), k), np.zeros((1, 3)), None, frame))
    with open_log(tmp_path / name) as log:
        for topic in ("/imu9", "/imu6", "/mixed"):
            fast, slow = log.imu(topic), log.imu(topic, fast=False)
            np.testing.assert_array_equal(fast.stamps, slow.stamps)
            np.testing.assert_array_equal(fast.acc, slow.acc)
            np.testing.assert_array_equal(fast.gyro, slow.gyro)
            assert fast.frame_id == slow.frame_id
            assert (fast.orientation_xyzw is None) == (slow.orientation_xyzw is None)
        imu9 = log.imu("/imu9")
    np.testing.assert_allclose(imu9.orientation_xyzw, q)
    np.testing.assert_allclose(imu9.acc, nine_axis.acc)
    np.testing.assert_allclose(imu9.stamps, t, atol=1e-9)
    assert imu9.frame_id == "imu_link_with_a_long_name"


def test_batched_imu_on_the_real_recording(real_ouster_mcap: Path) -> None:
    with open_log(real_ouster_mcap) as log:
        fast, slow = log.imu(), log.imu(fast=False)
    assert fast.stamps.size == 30
    assert fast.frame_id == slow.frame_id == "os_imu"
    np.testing.assert_array_equal(fast.stamps, slow.stamps)
    np.testing.assert_array_equal(fast.acc, slow.acc)
    np.testing.assert_array_equal(fast.gyro, slow.gyro)
    assert 9.3 < fast.acc[:, 2].mean() < 10.3  # gravity along the upright sensor z, m/s^2
