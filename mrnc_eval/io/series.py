"""Typed, header-stamped series out of one topic each: IMU, GNSS, JointState pairs, twists,
the planned path, poses, and the LiDAR sweeps (streamed one at a time).

Every series is validated once here (io/validate.py: finite values, unit quaternions,
plausible ranges): a few bad samples are dropped and noted, a stream with too many is
refused; then sorted by header stamp with exact duplicates dropped, the counts kept in the
log's HealthLedger. Topics come resolved (LogReader maps roles to topics).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mrnc_eval import geodesy
from mrnc_eval.data import GnssSeries, ImuSeries, SidePair, Sweep, Trajectory, Twists, Waypoints
from mrnc_eval.errors import InputError, NoGnssFix
from mrnc_eval.io.cloud_msg import parse_cloud
from mrnc_eval.io.config import IoConfig
from mrnc_eval.io.fast_imu import ImuBatch, decode_imu_batch
from mrnc_eval.io.log_source import LogSource
from mrnc_eval.io.pointcloud import CloudFormatError, decode_cloud
from mrnc_eval.io.pose_msg import PoseBatch, decode_pose_batch
from mrnc_eval.io.stream_health import HealthLedger
from mrnc_eval.io.validate import bad_lat_lon, bad_quaternions, beyond, non_finite, normalised

_IMU_BATCH = 65536  # messages decoded together (bounds the raw bytes held at once)
POSE_MSGTYPES = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseWithCovarianceStamped",
                 "geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/TransformStamped")


def stamp_of(msg: Any) -> float:
    """A message's header stamp (s)."""
    st = msg.header.stamp
    return float(st.sec) + float(st.nanosec) * 1e-9


@dataclass(frozen=True, kw_only=True)
class SeriesReader:
    """The typed extractors of one open log."""

    src: LogSource
    health: HealthLedger
    cfg: IoConfig

    def imu(self, topic: str, *, fast: bool = True) -> ImuSeries:
        """IMU samples sorted by header stamp, duplicates dropped (counted in `health`).
        Messages are decoded in batches straight from their bytes when their layout allows
        (see fast_imu); `fast=False` deserialises each message (same result, for checks)."""
        batches = self._imu_batches(topic, fast)
        t = np.concatenate([b.stamps for b in batches])
        quat = np.concatenate([b.orientation for b in batches])
        # REP-145: orientation_covariance[0] = -1 (or an all-zero quaternion): no orientation
        has_orientation = bool(np.all(np.concatenate([b.orientation_cov0 for b in batches]) >= 0)
                               and not np.any(np.all(quat == 0.0, axis=1)))
        acc = np.concatenate([b.acc for b in batches])
        gyro = np.concatenate([b.gyro for b in batches])
        v = self.cfg.validation
        checks = {"non-finite": non_finite(acc, gyro),
                  "acceleration out of range": beyond(acc, v.max_abs_acceleration_mps2),
                  "angular rate out of range": beyond(gyro, v.max_abs_angular_rate_rad_s)}
        if has_orientation:
            bad_q = bad_quaternions(quat, v.quat_norm_tolerance)
            if np.count_nonzero(bad_q) > v.max_bad_fraction * bad_q.size:  # a broken orientation filter:
                has_orientation = False  # the rates are still good, use the IMU as a 6-axis one
                self.health.note(topic, f"orientation ignored: {np.count_nonzero(bad_q)} of {bad_q.size} "
                                 "quaternions not finite or not unit norm (used as an IMU without orientation)")
            else:
                checks["orientation not a unit quaternion"] = bad_q
        valid = self.health.screen(topic, checks)
        keep = self.health.sorted_unique(t[valid], topic)
        quat_kept = normalised(quat[valid][keep]) if has_orientation else None
        return ImuSeries(t[valid][keep], acc[valid][keep], gyro[valid][keep], quat_kept, batches[-1].frame_id)

    def _imu_batches(self, topic: str, fast: bool) -> list[ImuBatch]:
        """The topic's messages decoded in batches of _IMU_BATCH (at least one batch)."""
        self.src.check_type(topic, ("sensor_msgs/msg/Imu",))
        ros1 = self.src.channel(topic).encoding == "ros1"
        batches: list[ImuBatch] = []
        for raws in _batched(self.src.raw(topic)):
            batch = decode_imu_batch(raws, ros1) if fast else None
            batches.append(batch if batch is not None else self._imu_batch_slow(raws, topic))
        if not batches:
            raise InputError(self.src.path, "IMU topic has no messages", topic=topic)
        return batches

    def _imu_batch_slow(self, raws: list[bytes], topic: str) -> ImuBatch:
        t, acc, gyro, quat, cov0, frame = [], [], [], [], [], ""
        for raw in raws:
            m = self.src.decode(raw, topic)
            t.append(stamp_of(m))
            a, g, q = m.linear_acceleration, m.angular_velocity, m.orientation
            acc.append((a.x, a.y, a.z))
            gyro.append((g.x, g.y, g.z))
            quat.append((q.x, q.y, q.z, q.w))
            cov0.append(m.orientation_covariance[0])
            frame = m.header.frame_id
        return ImuBatch(np.asarray(t, float), np.asarray(quat, float).reshape(-1, 4), np.asarray(cov0, float),
                        np.asarray(gyro, float).reshape(-1, 3), np.asarray(acc, float).reshape(-1, 3), str(frame))

    def gnss(self, topic: str) -> GnssSeries:
        t, lla, cov, no_fix, unknown_cov, frame = [], [], [], 0, 0, ""
        for m in self.src.messages(topic, ("sensor_msgs/msg/NavSatFix",)):
            if m.status.status < 0 or not np.isfinite([m.latitude, m.longitude, m.altitude]).all():
                no_fix += 1
                continue
            t.append(stamp_of(m))
            lla.append((m.latitude, m.longitude, m.altitude))
            c = np.asarray(m.position_covariance, float).reshape(3, 3)
            if m.position_covariance_type == 0 or not np.any(np.diag(c) > 0):  # COVARIANCE_TYPE_UNKNOWN
                c = np.diag(self.cfg.gnss_unknown_variance_m2).astype(float)
                unknown_cov += 1
            cov.append(c)
            frame = m.header.frame_id
        if not t:
            raise NoGnssFix(self.src.path, f"no valid GNSS fix ({no_fix} without fix)", topic=topic)
        valid = self.health.screen(topic, {"impossible latitude/longitude/altitude":
                                           bad_lat_lon(np.asarray(lla), self.cfg.validation.max_abs_altitude_m)})
        t_a, lla_a, cov_a = np.asarray(t)[valid], np.asarray(lla)[valid], np.asarray(cov)[valid]
        keep = self.health.sorted_unique(t_a, topic)
        if unknown_cov:
            self.health.note(topic, f"{unknown_cov} fix(es) without covariance: variance "
                             f"{self.cfg.gnss_unknown_variance_m2} m^2 assumed (io.gnss_unknown_variance_m2)")
        lla_a = lla_a[keep]
        origin = np.asarray(self.cfg.gnss_origin_lla if self.cfg.gnss_origin_lla is not None else lla_a[0], float)
        return GnssSeries(t_a[keep], lla_a, geodesy.lla_to_enu(lla_a, origin), cov_a[keep],
                          origin, n_no_fix=no_fix, frame_id=frame)

    def joint_pair(self, topic: str, *, scale: float, unit: str, exclude: str | None) -> SidePair:
        """Left and right velocities of a JointState topic (joints named left/right, those whose
        name holds `exclude` left out), times `scale`, in `unit`."""
        t, left, right = [], [], []
        for m in self.src.messages(topic, ("sensor_msgs/msg/JointState",)):
            names = [n.lower() for n in m.name]
            usable = [i for i, n in enumerate(names) if exclude is None or exclude not in n]
            idx_l = next((i for i in usable if "left" in names[i]), None)
            idx_r = next((i for i in usable if "right" in names[i]), None)
            if idx_l is None or idx_r is None or len(m.velocity) <= max(idx_l, idx_r):
                raise InputError(self.src.path, "JointState needs left/right joints with velocities, got "
                                 f"{list(m.name)}", topic=topic)
            t.append(stamp_of(m))
            left.append(m.velocity[idx_l])
            right.append(m.velocity[idx_r])
        if not t:
            raise InputError(self.src.path, "topic has no messages", topic=topic)
        lr = np.c_[np.asarray(left, float), np.asarray(right, float)] * scale
        checks = {"non-finite": non_finite(lr)}
        if unit == "m/s":
            checks["speed out of range"] = beyond(lr, self.cfg.validation.max_abs_speed_mps)
        valid = self.health.screen(topic, checks)
        t_a, lr = np.asarray(t)[valid], lr[valid]
        keep = self.health.sorted_unique(t_a, topic)
        return SidePair(t_a[keep], lr[keep, 0], lr[keep, 1], unit)

    def cmd_vel(self, topic: str) -> Twists:
        t, v, w = [], [], []
        for t_rec, m in self.src.timed_messages(topic, ("geometry_msgs/msg/TwistStamped", "geometry_msgs/msg/Twist")):
            tw = m.twist if hasattr(m, "twist") else m
            t.append(stamp_of(m) if hasattr(m, "header") else t_rec)  # plain Twist: record time
            v.append(tw.linear.x)
            w.append(tw.angular.z)
        return self._twists(topic, t, v, w)

    def odometry_twist(self, topic: str) -> Twists:
        """The body twist of an Odometry topic: forward speed m/s and yaw rate rad/s, in its
        child frame (nav_msgs/Odometry's convention)."""
        self.src.check_type(topic, ("nav_msgs/msg/Odometry",))
        batches = self._pose_batches(topic)
        t = np.concatenate([np.zeros(0)] + [b.stamps for b in batches])
        twist = np.concatenate([np.zeros((0, 6))] + [b.twist for b in batches if b.twist is not None])
        return self._twists(topic, t, twist[:, 0], twist[:, 5])

    def _twists(self, topic: str, t: Sequence[float] | np.ndarray, v: Sequence[float] | np.ndarray,
                w: Sequence[float] | np.ndarray) -> Twists:
        """Screened, sorted twists (non-finite or implausible speeds dropped and reported)."""
        if len(t) == 0:
            raise InputError(self.src.path, "topic has no messages", topic=topic)
        vw = np.c_[np.asarray(v, float), np.asarray(w, float)]
        valid = self.health.screen(topic, {"non-finite": non_finite(vw), "speed out of range":
                                           beyond(vw[:, :1], self.cfg.validation.max_abs_speed_mps)})
        t_a, vw = np.asarray(t)[valid], vw[valid]
        keep = self.health.sorted_unique(t_a, topic)
        return Twists(t_a[keep], vw[keep, 0], vw[keep, 1])

    def waypoints(self, topic: str) -> Waypoints:
        last = None
        for m in self.src.messages(topic, ("nav_msgs/msg/Path",)):
            last = m
        if last is None or not len(last.poses):
            raise InputError(self.src.path, "path topic has no poses", topic=topic)
        xy = np.asarray([(p.pose.position.x, p.pose.position.y) for p in last.poses], float)
        xy = xy[self.health.screen(topic, {"non-finite waypoint": non_finite(xy)})]
        return Waypoints(xy, stamp_of(last), last.header.frame_id)

    def poses(self, topic: str) -> Trajectory:
        """Poses of a PoseStamped / PoseWithCovarianceStamped / Odometry / TransformStamped topic."""
        batches = self._pose_batches(topic)
        if not batches:
            raise InputError(self.src.path, "pose topic has no messages", topic=topic)
        t = np.concatenate([b.stamps for b in batches])
        p = np.concatenate([b.position for b in batches])
        q = np.concatenate([b.orientation for b in batches])
        t_a, p_a, q_a = self.valid_poses(topic, t, p, q)
        keep = self.health.sorted_unique(t_a, topic)
        return Trajectory(t_a[keep], p_a[keep], q_a[keep], name=topic, frame_id=batches[-1].frame_id,
                          child_frame_id=batches[-1].child_frame_id)

    def _pose_batches(self, topic: str, *, fast: bool = True) -> list[PoseBatch]:
        """The topic's pose messages decoded in batches of _IMU_BATCH, straight from their bytes
        when they allow (io/pose_msg.py), else through the library (none without messages)."""
        self.src.check_type(topic, None)
        msgtype, ros1 = self.src.msgtype(topic), self.src.channel(topic).encoding == "ros1"
        batches: list[PoseBatch] = []
        for raws in _batched(self.src.raw(topic)):
            if msgtype not in POSE_MSGTYPES:
                raise InputError(self.src.path, f"{msgtype} is not a pose type (PoseStamped, Odometry, ...)",
                                 topic=topic)
            batch = decode_pose_batch(raws, msgtype, ros1=ros1) if fast else None
            batches.append(batch if batch is not None else self._pose_batch_slow(raws, topic, msgtype))
        return batches

    def _pose_batch_slow(self, raws: list[bytes], topic: str, msgtype: str) -> PoseBatch:
        t, p, q, twist, frame, child = [], [], [], [], "", ""
        for raw in raws:
            m = self.src.decode(raw, topic)
            position, o, child = _pose_fields(msgtype, m, child)
            t.append(stamp_of(m))
            p.append((position.x, position.y, position.z))
            q.append((o.x, o.y, o.z, o.w))
            if msgtype == "nav_msgs/msg/Odometry":
                lin, ang = m.twist.twist.linear, m.twist.twist.angular
                twist.append((lin.x, lin.y, lin.z, ang.x, ang.y, ang.z))
            frame = m.header.frame_id
        return PoseBatch(stamps=np.asarray(t, float), position=np.asarray(p, float).reshape(-1, 3),
                         orientation=np.asarray(q, float).reshape(-1, 4),
                         twist=np.asarray(twist, float).reshape(-1, 6) if twist else None,
                         frame_id=str(frame), child_frame_id=str(child))

    def valid_poses(self, topic: str, t: Sequence[float] | np.ndarray,
                    p: Sequence[tuple[float, float, float]] | np.ndarray,
                    q: Sequence[tuple[float, float, float, float]] | np.ndarray,
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Poses with finite, plausible positions and unit quaternions (normalised)."""
        p_a, q_a = np.asarray(p, float).reshape(-1, 3), np.asarray(q, float).reshape(-1, 4)
        v = self.cfg.validation
        valid = self.health.screen(topic, {"non-finite position": non_finite(p_a),
                                           "position out of range": beyond(p_a, v.max_abs_position_m),
                                           "orientation not a unit quaternion":
                                               bad_quaternions(q_a, v.quat_norm_tolerance)})
        return np.asarray(t, float)[valid], p_a[valid], normalised(q_a[valid])

    def sweeps(self, topic: str, *, keep: Callable[[float], bool] | None = None,
               note_skips: bool = True) -> Iterator[Sweep]:
        """Decoded sweeps in log order, streamed one at a time. A sweep whose header stamp is not
        after the last one yielded (a duplicate or out-of-order cloud) is skipped and noted in the
        health (`note_skips` False: not noted, for a look at the first sweeps before the run, whose
        own pass notes them; noted twice they read as twice the skips). `keep` is asked with each
        remaining header stamp before decoding; False skips the sweep undecoded (a mapping rate below
        the sensor rate: slam/mapping_interval.py)."""
        msgtype = self.src.msgtype(topic)
        if msgtype != "sensor_msgs/msg/PointCloud2":
            raise InputError(self.src.path, f"expected sensor_msgs/msg/PointCloud2, got {msgtype}", topic=topic)
        last = -np.inf
        skipped = 0
        ros1 = self.src.channel(topic).encoding == "ros1"
        try:
            for _t, raw in self.src.stream(topic):
                stamp = self.src.checked_header_stamp(raw, topic)
                if stamp <= last:
                    skipped += 1
                    continue
                if keep is not None and not keep(stamp):
                    continue
                m = parse_cloud(raw, ros1=ros1) or self.src.decode(bytes(raw), topic)
                try:
                    sweep = decode_cloud(m, stamp_of(m))
                except CloudFormatError as err:
                    raise InputError(self.src.path, str(err), topic=topic) from err
                last = stamp
                yield sweep
        finally:
            if skipped and note_skips:
                self.health.note(topic, f"{skipped} sweep(s) skipped: header stamp not after the previous sweep")

    def strings(self, topic: str) -> list[str]:
        return [str(m.data) for m in self.src.messages(topic, ("std_msgs/msg/String",))]


def _batched(records: Iterator[tuple[int, bytes]]) -> Iterator[list[bytes]]:
    """The messages' bytes in lists of _IMU_BATCH (bounds the raw bytes held at once)."""
    pending: list[bytes] = []
    for _t, raw in records:
        pending.append(bytes(raw))
        if len(pending) >= _IMU_BATCH:
            yield pending
            pending = []
    if pending:
        yield pending


def _pose_fields(msgtype: str, m: Any, child: str) -> tuple[Any, Any, str]:
    """(position, orientation, child frame) of one pose message (`child` kept when the type has none)."""
    if msgtype == "nav_msgs/msg/Odometry":
        return m.pose.pose.position, m.pose.pose.orientation, m.child_frame_id
    if msgtype == "geometry_msgs/msg/PoseWithCovarianceStamped":
        return m.pose.pose.position, m.pose.pose.orientation, child
    if msgtype == "geometry_msgs/msg/PoseStamped":
        return m.pose.position, m.pose.orientation, child
    return m.transform.translation, m.transform.rotation, m.child_frame_id  # TransformStamped
