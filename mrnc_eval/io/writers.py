"""LogWriter: real ROS bags through rosbags' writers (ROS 2 MCAP/zstd, ROS 2 sqlite3, ROS 1).

Messages are written in header-stamp order, as a recorder would: whole series (IMU,
GNSS, odometry...) are buffered and merged in front of each point cloud, which is
written as soon as it is given (clouds must come in time order). The log is written
under a temporary name and moved into place on a clean close, so a failed run leaves
no file that could pass for a log.
"""

from __future__ import annotations

import contextlib
import heapq
import shutil
import tempfile
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from mrnc_eval.data import ImuSeries, Trajectory, Twists, Waypoints
from mrnc_eval.errors import InputError, OutputError, UsageError
from mrnc_eval.io import messages as M
from mrnc_eval.io.containers import FORMAT_NAMES, SUFFIX_FORMAT
from mrnc_eval.io.typestore import typestore_for

Format = Literal["mcap", "db3", "bag"]


def _latched_qos() -> list[Any]:
    """ROS 2 QoS of a latched topic (/tf_static): reliable, transient local, keep last 1."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    infinite = QosTime(2147483647, 4294967295)
    return [Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL, infinite,
                infinite, QosLiveliness.AUTOMATIC, infinite, False)]


def _ns(t: float) -> int:
    return int(round(t * 1e9))


class LogWriter:
    """Write a robot log. `path` ending in .mcap/.db3 gives a single file; otherwise a
    ROS 2 bag directory (for mcap/db3) or a ROS 1 bag file (for bag). A log suffix that names
    another format is refused (`x.bag` as MCAP would be a folder no reader takes for a ROS 1 bag)."""

    def __init__(self, path: str | Path, fmt: Format = "mcap", *, ros1_compression: str | None = "lz4") -> None:
        self.path = Path(path)
        self.fmt = fmt
        named = SUFFIX_FORMAT.get(self.path.suffix.lower(), fmt)
        if named != fmt:
            raise UsageError(f"{self.path}: a {self.path.suffix} name is a {FORMAT_NAMES[named]}, but the format "
                             f"asked for is {fmt} ({FORMAT_NAMES.get(fmt, 'unknown')})")
        self.ros1 = fmt == "bag"
        self.ts = typestore_for(ros1=self.ros1)
        parent = self.path.parent if self.path.parent.exists() else None  # same filesystem: the final move is a rename
        self._tmpdir = Path(tempfile.mkdtemp(prefix=".mrnc-write-", dir=parent))
        self._pending: list[tuple[int, int, Any, bytes]] = []  # heap of (stamp ns, order, conn, raw)
        self._order = 0
        self._conns: dict[str, Any] = {}
        self._seq: dict[str, int] = {}
        if self.ros1:
            from rosbags.rosbag1 import Writer as Writer1

            self._inner_path = self._tmpdir / "log.bag"
            self._writer: Any = Writer1(self._inner_path)  # rosbags' ROS 1 or ROS 2 writer
            if ros1_compression:
                self._writer.set_compression(getattr(Writer1.CompressionFormat, ros1_compression.upper()))
        else:
            from rosbags.rosbag2 import StoragePlugin
            from rosbags.rosbag2 import Writer as Writer2
            from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

            name = self.path.name
            for suffix in (".mcap", ".db3"):
                name = name.removesuffix(suffix)
            self._inner_path = self._tmpdir / (name or "log")
            plugin = StoragePlugin.MCAP if fmt == "mcap" else StoragePlugin.SQLITE3
            self._writer = Writer2(self._inner_path, version=8, storage_plugin=plugin)
            if fmt == "mcap":
                self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        self._writer.open()
        self._closed = False

    # ------------------------------------------------------------------ plumbing

    def _conn(self, topic: str, msgtype: str, latched: bool = False) -> Any:
        conn = self._conns.get(topic)
        if conn is None:
            if self.ros1:
                conn = self._writer.add_connection(topic, msgtype, typestore=self.ts, latching=1 if latched else None)
            else:
                conn = self._writer.add_connection(topic, msgtype, typestore=self.ts,
                                                   offered_qos_profiles=_latched_qos() if latched else ())
            self._conns[topic] = conn
        return conn

    def _serialize(self, msg: Any, msgtype: str) -> bytes:
        if self.ros1:
            return bytes(self.ts.serialize_ros1(msg, msgtype))
        return bytes(self.ts.serialize_cdr(msg, msgtype))

    def _next_seq(self, topic: str) -> int:
        s = self._seq.get(topic, 0)
        self._seq[topic] = s + 1
        return s

    def _queue(self, topic: str, msgtype: str, t: float, msg: Any) -> None:
        conn = self._conn(topic, msgtype)
        heapq.heappush(self._pending, (_ns(t), self._order, conn, self._serialize(msg, msgtype)))
        self._order += 1

    def _flush_until(self, t_ns: int | None) -> None:
        while self._pending and (t_ns is None or self._pending[0][0] <= t_ns):
            stamp, _, conn, raw = heapq.heappop(self._pending)
            self._writer.write(conn, stamp, raw)

    # ------------------------------------------------------------------ message series

    def write_imu(self, topic: str, imu: ImuSeries, *, acc_var: float = 0.01, gyro_var: float = 6e-4) -> None:
        q = imu.orientation_xyzw
        for i, t in enumerate(imu.stamps):
            msg = M.imu(self.ts, float(t), imu.frame_id, imu.acc[i], imu.gyro[i], None if q is None else q[i],
                        self.ros1, self._next_seq(topic), acc_var, gyro_var)
            self._queue(topic, "sensor_msgs/msg/Imu", float(t), msg)

    def write_ouster_cloud(self, topic: str, stamp: float, xyz: ArrayLike, t_ns: ArrayLike, range_mm: ArrayLike,
                           reflectivity: ArrayLike, intensity: ArrayLike, ambient: ArrayLike,
                           frame_id: str = "os_sensor") -> None:
        """One organised sweep (H x W arrays); buffered messages up to `stamp` go first."""
        self._flush_until(_ns(stamp))
        msg = M.ouster_cloud(self.ts, stamp, frame_id, xyz, t_ns, range_mm, reflectivity, intensity, ambient,
                             self.ros1, self._next_seq(topic))
        conn = self._conn(topic, "sensor_msgs/msg/PointCloud2")
        self._writer.write(conn, _ns(stamp), self._serialize(msg, "sensor_msgs/msg/PointCloud2"))

    def write_returns_cloud(self, topic: str, stamp: float, xyz: ArrayLike, t_ns: ArrayLike, intensity: ArrayLike,
                            ring: ArrayLike, frame_id: str = "os_sensor") -> None:
        """One sweep's returns as an unorganised cloud (N points); buffered messages up to `stamp` go first."""
        self._flush_until(_ns(stamp))
        msg = M.returns_cloud(self.ts, stamp, frame_id, xyz, t_ns, intensity, ring, self.ros1, self._next_seq(topic))
        conn = self._conn(topic, "sensor_msgs/msg/PointCloud2")
        self._writer.write(conn, _ns(stamp), self._serialize(msg, "sensor_msgs/msg/PointCloud2"))

    def write_navsatfix(self, topic: str, stamps: np.ndarray, lla: np.ndarray, covariance: np.ndarray,
                        status: np.ndarray, frame_id: str = "gnss") -> None:
        for i, t in enumerate(stamps):
            msg = M.navsatfix(self.ts, float(t), frame_id, lla[i], covariance[i], status[i], self.ros1,
                              self._next_seq(topic))
            self._queue(topic, "sensor_msgs/msg/NavSatFix", float(t), msg)

    def write_joint_state(self, topic: str, stamps: np.ndarray, names: list[str], velocity: ArrayLike) -> None:
        velocity = np.asarray(velocity, dtype=float)
        for i, t in enumerate(stamps):
            msg = M.joint_state(self.ts, float(t), names, velocity[i], self.ros1, self._next_seq(topic))
            self._queue(topic, "sensor_msgs/msg/JointState", float(t), msg)

    def write_odometry(self, topic: str, traj: Trajectory, frame_id: str = "map", child_frame_id: str = "base_link",
                       linear_velocity: ArrayLike | None = None, angular_velocity: ArrayLike | None = None) -> None:
        zeros = np.zeros((len(traj), 3))
        lin = zeros if linear_velocity is None else np.asarray(linear_velocity)
        ang = zeros if angular_velocity is None else np.asarray(angular_velocity)
        for i, t in enumerate(traj.stamps):
            msg = M.odometry(self.ts, float(t), frame_id, child_frame_id, traj.positions[i], traj.quat_xyzw[i],
                             lin[i], ang[i], self.ros1, self._next_seq(topic))
            self._queue(topic, "nav_msgs/msg/Odometry", float(t), msg)

    def write_path(self, topic: str, waypoints: Waypoints, stamp: float) -> None:
        msg = M.path(self.ts, stamp, waypoints.frame_id or "map", waypoints.xy, self.ros1)
        self._queue(topic, "nav_msgs/msg/Path", stamp, msg)

    def write_twist_stamped(self, topic: str, twists: Twists, frame_id: str = "base_link") -> None:
        for i, t in enumerate(twists.stamps):
            msg = M.twist_stamped(self.ts, float(t), frame_id, twists.v[i], twists.omega[i], self.ros1,
                                  self._next_seq(topic))
            self._queue(topic, "geometry_msgs/msg/TwistStamped", float(t), msg)

    def write_tf_static(self, transforms: list[tuple[str, str, np.ndarray]], stamp: float) -> None:
        msg = M.tf_message(self.ts, stamp, transforms, self.ros1)
        self._conn("/tf_static", "tf2_msgs/msg/TFMessage", latched=True)
        self._queue("/tf_static", "tf2_msgs/msg/TFMessage", stamp, msg)

    def write_strings(self, topic: str, stamps: np.ndarray, texts: list[str]) -> None:
        for t, text in zip(stamps, texts, strict=True):
            self._queue(topic, "std_msgs/msg/String", float(t), M.string(self.ts, text))

    # ------------------------------------------------------------------ lifecycle

    def close(self) -> Path:
        """Flush, close and move the finished log into place; returns its path."""
        if self._closed:
            return self.path
        self._flush_until(None)
        self._writer.close()
        self._closed = True
        if self.fmt == "mcap":  # rosbags writes no chunk CRCs: without them a flipped byte goes unnoticed
            from mrnc_eval.io.integrity import add_chunk_crcs

            for f in self._inner_path.glob("*.mcap"):
                add_chunk_crcs(f)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.path.exists():
            self._remove_previous_log()
        if self.ros1:
            src = self._inner_path
        elif self.path.suffix.lower() in (".mcap", ".db3"):
            files = [p for p in self._inner_path.iterdir() if p.suffix == self.path.suffix.lower()]
            if len(files) != 1:
                raise InputError(self.path, f"expected one {self.path.suffix} file from the bag writer")
            src = files[0]
        else:
            src = self._inner_path
        shutil.move(str(src), self.path)
        shutil.rmtree(self._tmpdir, ignore_errors=True)
        return self.path

    def _remove_previous_log(self) -> None:
        """Replace only a log: a file, an empty folder, or a ROS 2 bag folder (metadata.yaml and
        .mcap/.db3 files); a folder holding anything else is never deleted."""
        if self.path.is_dir() and not self.path.is_symlink():
            inside = list(self.path.iterdir())
            if any(not p.is_file() or p.suffix not in (".mcap", ".db3", ".yaml") for p in inside):
                raise OutputError(self.path, "folder holds files that are not a bag; not replaced")
            for p in inside:
                p.unlink()
            self.path.rmdir()
        else:
            self.path.unlink()

    def abort(self) -> None:
        if not self._closed:
            with contextlib.suppress(Exception):
                self._writer.close()
            self._closed = True
        shutil.rmtree(self._tmpdir, ignore_errors=True)

    def __enter__(self) -> LogWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
