"""LogReader: typed, header-stamped time series out of ROS 1 / ROS 2 logs.

Every library exception is turned into an InputError naming file, topic and problem at
this boundary. Streams are sorted by header stamp; duplicate and out-of-order stamps are
counted (StreamHealth), never silently passed on. Every typed series is validated once here
(io/validate.py: finite values, unit quaternions, plausible ranges): a few bad samples are
dropped and noted, a stream with too many is refused. Sweeps are streamed one at a time.
"""

from __future__ import annotations

import contextlib
import glob
import logging
import struct
from array import array
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from mrnc_eval import geodesy
from mrnc_eval.data import GnssSeries, ImuSeries, SidePair, StreamHealth, Sweep, Trajectory, Twists, Waypoints
from mrnc_eval.errors import InputError, NoGnssFix
from mrnc_eval.io.chunk_prefix import WHOLE, IndexUnusable
from mrnc_eval.io.config import IoConfig
from mrnc_eval.io.containers import describe_error, detect_container, openable
from mrnc_eval.io.fast_imu import ImuBatch, decode_imu_batch
from mrnc_eval.io.mcap_index import overview as mcap_overview
from mrnc_eval.io.pointcloud import CloudFormatError, decode_cloud
from mrnc_eval.io.roles import Ambiguity, Candidate, TruthExclusion, candidates_by_role, choose_roles
from mrnc_eval.io.sources import Channel, McapSource, RosbagsSource
from mrnc_eval.io.split_logs import SplitSource, split_log_paths
from mrnc_eval.io.validate import Mask, bad_lat_lon, bad_quaternions, beyond, non_finite, normalised, screen

log = logging.getLogger(__name__)

_BULK_TYPES = {  # never kept in memory by the overview pass
    "sensor_msgs/msg/PointCloud2", "sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage",
    "sensor_msgs/msg/LaserScan",
}
_STAMPED_FIRST_FIELD = {  # message types whose first field is std_msgs/Header
    "sensor_msgs/msg/PointCloud2", "sensor_msgs/msg/Imu", "sensor_msgs/msg/NavSatFix", "sensor_msgs/msg/JointState",
    "nav_msgs/msg/Odometry", "nav_msgs/msg/Path", "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped", "geometry_msgs/msg/TwistStamped",
    "geometry_msgs/msg/TransformStamped",
}


_HEADER_BYTES = 12  # serialised bytes up to the end of a header stamp (ROS 1 and CDR)
_IMU_BATCH = 65536  # messages decoded together (bounds the raw bytes held at once)


@dataclass(frozen=True)
class TopicInfo:
    topic: str
    msgtype: str
    count: int
    role: str | None
    rate_hz: float
    max_gap_s: float
    first_s: float | None
    last_s: float | None
    duplicates: int
    out_of_order: int
    problem: str | None = None  # why the topic cannot be decoded (unknown type, unsupported encoding)


def _stamp(msg: Any) -> float:
    st = msg.header.stamp
    return float(st.sec) + float(st.nanosec) * 1e-9


def _quat_to_matrix(q: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    matrix: np.ndarray = Rotation.from_quat(q).as_matrix()
    return matrix


def _sort_dedup(stamps: np.ndarray, topic: str) -> tuple[np.ndarray, StreamHealth]:
    """Indices that sort by stamp and drop exact duplicates; the health of the raw stream."""
    n = stamps.size
    out_of_order = int(np.count_nonzero(np.diff(stamps) < 0)) if n > 1 else 0
    order = np.argsort(stamps, kind="stable")
    s = stamps[order]
    keep = np.ones(n, dtype=bool)
    if n > 1:
        keep[1:] = np.diff(s) > 0
    dup = int(n - keep.sum())
    gaps = np.diff(s[keep])
    health = StreamHealth(topic=topic, count=n, duplicates=dup, out_of_order=out_of_order,
                          max_gap_s=float(gaps.max()) if gaps.size else 0.0)
    return order[keep], health


class LogReader:
    """An open log. Use `open_log(path)`; close it (or use `with`)."""

    def __init__(self, paths: list[Path], io_cfg: IoConfig | None = None) -> None:
        self.paths = paths
        self.path = paths[0]
        self.cfg = io_cfg or IoConfig()
        self.container = detect_container(paths)
        self._links = contextlib.ExitStack()  # rosbags' view of files whose suffix is not theirs; closed with the log
        try:
            self._src = self._open_source(self._links.enter_context(openable(paths, self.container)))
        except InputError:
            self._links.close()
            raise
        except Exception as err:  # rosbags/mcap/sqlite raise many unrelated types for broken files
            self._links.close()
            raise InputError(self.path, f"cannot open {self.container} log: {describe_error(err)}") from err
        self._channels = self._src.channels
        if not self._channels:
            self.close()
            raise InputError(self.path, "log has no topics (empty bag)")
        self._stats: dict[str, TopicInfo] | None = None
        self._health: dict[str, StreamHealth] = {}
        self._roles: dict[str, str] | None = None
        self.role_doubts: list[Ambiguity | TruthExclusion] = []  # io/roles.py rules 3 and 4
        self._stamps: dict[str, np.ndarray] = {}
        self._cache: dict[str, list[tuple[int, bytes]]] = {}  # small topics' raw messages from the overview pass

    def _open_source(self, named: list[Path]) -> McapSource | RosbagsSource | SplitSource:
        """The reading library for the container; `named`: the paths as rosbags can open them."""
        if self.container != "ros1" and len(named) > 1:  # split ROS 2 / MCAP: one source per file
            return SplitSource([McapSource(p) if self.container == "mcap" else RosbagsSource([p], ros1=False)
                                for p in named], self.paths)
        if self.container == "mcap":
            return McapSource(self.path)
        return RosbagsSource(named, ros1=self.container == "ros1")

    # ------------------------------------------------------------------ lifecycle
    def close(self) -> None:
        with contextlib.suppress(Exception):
            self._src.close()
        self._links.close()

    def __enter__(self) -> LogReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ raw access
    def _channel(self, topic: str) -> Channel:
        ch = self._channels.get(topic)
        if ch is None:
            names = sorted(self._channels)
            listed = ", ".join(names[:12]) + (f", ... ({len(names)} in all)" if len(names) > 12 else "")
            raise InputError(self.path, f"topic not in log (topics: {listed})", topic=topic)
        return ch

    def _msgtype(self, topic: str) -> str:
        return self._channel(topic).msgtype

    def _iterate(self, topics: list[str]) -> Iterator[tuple[str, int, bytes]]:
        """(topic, record time ns, raw message) in log order; library errors become InputError."""
        try:
            yield from self._src.messages(topics)
        except InputError:
            raise
        except Exception as err:
            where = topics[0] if len(topics) == 1 else None
            raise InputError(self.path, f"corrupted or truncated data: {describe_error(err)}", topic=where) from err

    def _raw(self, topic: str) -> Iterator[tuple[int, bytes]]:
        ch = self._channel(topic)
        if ch.problem:
            raise InputError(self.path, ch.problem, topic=topic)
        if topic in self._cache:
            yield from self._cache[topic]
            return
        for _topic, t_rec, raw in self._iterate([topic]):
            yield t_rec, raw

    def _decode(self, raw: bytes, topic: str) -> Any:  # a rosbags message object
        try:
            return self._src.deserialize(raw, topic)
        except Exception as err:
            raise InputError(self.path, f"cannot decode {self._msgtype(topic)} message: {describe_error(err)}",
                             topic=topic) from err

    def _messages(self, topic: str, expect: tuple[str, ...] | None = None) -> Iterator[Any]:
        for _t, msg in self._timed_messages(topic, expect):
            yield msg

    def _check_type(self, topic: str, expect: tuple[str, ...] | None) -> None:
        """The topic is decodable and (with `expect`) carries one of those types."""
        ch = self._channel(topic)
        if ch.problem:
            raise InputError(self.path, ch.problem, topic=topic)
        if expect is not None and ch.msgtype not in expect:
            raise InputError(self.path, f"expected {' or '.join(expect)}, got {ch.msgtype}", topic=topic)

    def _timed_messages(self, topic: str, expect: tuple[str, ...] | None = None) -> Iterator[tuple[float, Any]]:
        """(record time s, message); with `expect`, the topic must carry one of those types."""
        self._check_type(topic, expect)
        for t_rec, raw in self._raw(topic):
            yield t_rec * 1e-9, self._decode(raw, topic)

    def _raw_header_stamp(self, raw: bytes, topic: str | None = None) -> float:
        """Header stamp straight from the serialised bytes (no full decode).
        ROS 1: seq u32, then sec u32, nsec u32. CDR: 4-byte encapsulation header (byte 1 odd:
        little endian), then sec i32, nanosec u32."""
        ros1 = self._channels[topic].encoding == "ros1" if topic else self.container == "ros1"
        if ros1:
            sec, nsec = struct.unpack_from("<II", raw, 4)
        else:
            sec, nsec = struct.unpack_from("<iI" if raw[1] & 1 else ">iI", raw, 4)
        return float(sec + nsec * 1e-9)

    # ------------------------------------------------------------------ overview
    @property
    def topics(self) -> list[TopicInfo]:
        if self._stats is None:
            self._scan()
        return list(self._stats.values())  # type: ignore[union-attr]

    def _scan(self) -> None:
        """One pass over the whole log: header stamps (record times for unstamped types),
        counts and gaps per topic; the raw messages of small topics are kept (io.small_topic_cache_mb)."""
        header_topics = {t for t, ch in self._channels.items()
                         if ch.msgtype in _STAMPED_FIRST_FIELD and ch.encoding in ("ros1", "cdr")}
        keep = {t for t, ch in self._channels.items() if ch.msgtype not in _BULK_TYPES and not ch.problem}
        wants = {t: WHOLE if t in keep else _HEADER_BYTES if t in header_topics else 0 for t in self._channels}
        try:  # MCAP, ROS 1: from the indexes, the clouds left compressed (io/chunk_prefix.py)
            stamps, cache = self._collect(self._indexed_overview(wants), header_topics, keep)
        except Exception:  # no usable index, or a broken log: the full read, and its own error
            stamps, cache = self._collect(self._iterate(list(self._channels)), header_topics, keep)
        self._cache = cache
        stats: dict[str, TopicInfo] = {}
        self._stamps = {t: np.frombuffer(v, dtype=np.float64) if len(v) else np.zeros(0) for t, v in stamps.items()}
        for topic, ch in self._channels.items():
            arr = self._stamps[topic]
            _, health = _sort_dedup(arr, topic)
            self._set_health(health)
            span = float(arr.max() - arr.min()) if arr.size > 1 else 0.0
            stats[topic] = TopicInfo(
                topic=topic, msgtype=ch.msgtype, count=int(arr.size), role=None,
                rate_hz=(arr.size - 1) / span if span > 0 else 0.0, max_gap_s=health.max_gap_s,
                first_s=float(arr.min()) if arr.size else None, last_s=float(arr.max()) if arr.size else None,
                duplicates=health.duplicates, out_of_order=health.out_of_order, problem=ch.problem,
            )
        by_topic: dict[str, str] = {}
        for role, topic in self.roles.items():
            by_topic.setdefault(topic, role)
        self._stats = {t: TopicInfo(**{**s.__dict__, "role": by_topic.get(t)}) for t, s in stats.items()}

    def _indexed_overview(self, wants: dict[str, int]) -> Iterator[tuple[str, int, bytes]]:
        """The overview's messages from the container's indexes (MCAP files, file after file as a
        split log is read; ROS 1 bags); IndexUnusable when the log has none that can be trusted."""
        if self.container == "ros1" and isinstance(self._src, RosbagsSource):
            yield from self._src.indexed_overview(list(self._channels), wants)
            return
        if self.container not in ("mcap", "ros2-mcap") or not all(p.is_file() for p in self.paths):
            raise IndexUnusable(self.container)
        for path in self.paths:
            for topic, t_rec, data in mcap_overview(path, wants):
                if topic in self._channels:
                    yield topic, t_rec, data

    def _collect(self, records: Iterable[tuple[str, int, bytes]], header_topics: set[str],
                 keep: set[str]) -> tuple[dict[str, array[float]], dict[str, list[tuple[int, bytes]]]]:
        """Stamps of every topic and the small topics' messages (none when over the cache budget)."""
        stamps = {t: array("d") for t in self._channels}  # 8 bytes a stamp (a list costs 32)
        budget = int(self.cfg.small_topic_cache_mb * 1e6)
        cache: dict[str, list[tuple[int, bytes]]] = {t: [] for t in keep}
        for topic, t_rec, raw in records:
            if topic in keep:
                budget -= len(raw)
                if budget >= 0:
                    cache[topic].append((t_rec, bytes(raw)))
            if topic in header_topics:
                try:
                    stamps[topic].append(self._raw_header_stamp(raw, topic))
                except (struct.error, IndexError) as err:
                    raise InputError(self.path, f"message too short for a header: {err}", topic=topic) from err
            else:
                stamps[topic].append(t_rec * 1e-9)
        return stamps, cache if budget >= 0 else {}  # over budget: each series reads the file again

    def topic_types(self) -> dict[str, str]:
        """topic -> message type, from the container's index (no scan)."""
        return {t: ch.msgtype for t, ch in self._channels.items()}

    @property
    def roles(self) -> dict[str, str]:
        """role -> topic, from message types and the container's index (no scan of the log:
        only the first message of each JointState topic is read, for its joint names)."""
        if self._roles is None:
            self._roles = self._detect_roles()
        return dict(self._roles)

    def _detect_roles(self) -> dict[str, str]:
        joint_names: dict[str, list[str]] = {}
        for topic, ch in self._channels.items():
            if ch.msgtype == "sensor_msgs/msg/JointState" and not ch.problem and ch.count != 0:
                for _t, raw in self._raw(topic):
                    joint_names[topic] = [str(n) for n in self._decode(raw, topic).name]
                    break
        found = candidates_by_role([Candidate(t, ch.msgtype, ch.count) for t, ch in self._channels.items()],
                                   joint_names)
        for role in ("lidar", "wheel_odom"):  # several candidates: their first message's fields and frames count
            if len(found.get(role, ())) > 1 and role not in self.cfg.roles:
                found[role] = [self._with_evidence(c) for c in found[role]]
        roles, self.role_doubts = choose_roles(found, self.cfg.roles)
        for doubt in self.role_doubts:
            log.warning("%s: %s", self.path, doubt.message())
        for role, topic in roles.items():
            if topic not in self._channels:
                raise InputError(self.path, f"topic given for role {role!r} is not in the log", topic=topic)
        return roles

    def _with_evidence(self, c: Candidate) -> Candidate:
        """`c` with the field names and frames of its first message (unchanged if it cannot be read)."""
        try:
            msg = next((self._decode(raw, c.topic) for _t, raw in self._raw(c.topic)), None)
        except InputError:
            return c
        if msg is None:
            return c
        fields = tuple(str(f.name) for f in getattr(msg, "fields", ()))
        return replace(c, fields=fields, frame_id=str(msg.header.frame_id),
                       child_frame_id=str(getattr(msg, "child_frame_id", "")))

    def _topic_for(self, role: str, topic: str | None) -> str:
        if topic is not None:
            if topic not in self._channels:
                raise InputError(self.path, "requested topic is absent", topic=topic)
            return topic
        found = self.roles.get(role)
        if found is None:
            raise InputError(self.path, f"no topic with role {role!r} (set io.roles.{role} to choose one)")
        return found

    @property
    def start_s(self) -> float:
        firsts = [s.first_s for s in self.topics if s.first_s is not None and s.role not in ("tf_static", "path")]
        return min(firsts) if firsts else 0.0

    @property
    def end_s(self) -> float:
        lasts = [s.last_s for s in self.topics if s.last_s is not None and s.role not in ("tf_static", "path")]
        return max(lasts) if lasts else 0.0

    @property
    def duration_s(self) -> float:
        return self.end_s - self.start_s

    def health(self, topic: str) -> StreamHealth:
        """Counts of the raw stream (duplicates, out-of-order stamps, largest gap) and notes
        from reading it (e.g. sweeps skipped)."""
        if self._stats is None:
            self._scan()
        if topic not in self._health:
            raise InputError(self.path, "topic not in log", topic=topic)
        return self._health[topic]

    def has_role(self, role: str) -> bool:
        return role in self.roles

    # ------------------------------------------------------------------ typed series
    def imu(self, topic: str | None = None, *, fast: bool = True) -> ImuSeries:
        """IMU samples sorted by header stamp, duplicates dropped (counted in `health`).
        Messages are decoded in batches straight from their bytes when their layout allows
        (see fast_imu); `fast=False` deserialises each message (same result, for checks)."""
        topic = self._topic_for("imu", topic)
        self._check_type(topic, ("sensor_msgs/msg/Imu",))
        ros1 = self._channel(topic).encoding == "ros1"
        batches: list[ImuBatch] = []
        pending: list[bytes] = []

        def flush() -> None:
            batch = decode_imu_batch(pending, ros1) if fast else None
            batches.append(batch if batch is not None else self._imu_batch_slow(pending, topic))
            pending.clear()

        for _t, raw in self._raw(topic):
            pending.append(bytes(raw))
            if len(pending) >= _IMU_BATCH:
                flush()
        if pending:
            flush()
        if not batches:
            raise InputError(self.path, "IMU topic has no messages", topic=topic)
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
                self._note(topic, f"orientation ignored: {np.count_nonzero(bad_q)} of {bad_q.size} quaternions "
                           "not finite or not unit norm (used as an IMU without orientation)")
            else:
                checks["orientation not a unit quaternion"] = bad_q
        valid = self._screen(topic, checks)
        keep, health = _sort_dedup(t[valid], topic)
        self._set_health(health)
        quat_kept = normalised(quat[valid][keep]) if has_orientation else None
        return ImuSeries(t[valid][keep], acc[valid][keep], gyro[valid][keep], quat_kept, batches[-1].frame_id)

    def _imu_batch_slow(self, raws: list[bytes], topic: str) -> ImuBatch:
        t, acc, gyro, quat, cov0, frame = [], [], [], [], [], ""
        for raw in raws:
            m = self._decode(raw, topic)
            t.append(_stamp(m))
            a, g, q = m.linear_acceleration, m.angular_velocity, m.orientation
            acc.append((a.x, a.y, a.z))
            gyro.append((g.x, g.y, g.z))
            quat.append((q.x, q.y, q.z, q.w))
            cov0.append(m.orientation_covariance[0])
            frame = m.header.frame_id
        return ImuBatch(np.asarray(t, float), np.asarray(quat, float).reshape(-1, 4), np.asarray(cov0, float),
                        np.asarray(gyro, float).reshape(-1, 3), np.asarray(acc, float).reshape(-1, 3), str(frame))

    def sweeps(self, topic: str | None = None, *, min_interval_s: float = 0.0) -> Iterator[Sweep]:
        """Decoded sweeps in log order, streamed one at a time. A sweep whose header stamp is not
        after the last one yielded (a duplicate or out-of-order cloud) is skipped and counted in
        `health(topic).notes`. With min_interval_s, a sweep closer than that to the last one
        yielded is skipped before it is decoded (a mapping rate below the sensor rate)."""
        topic = self._topic_for("lidar", topic)
        msgtype = self._msgtype(topic)
        if msgtype != "sensor_msgs/msg/PointCloud2":
            raise InputError(self.path, f"expected sensor_msgs/msg/PointCloud2, got {msgtype}", topic=topic)
        last = -np.inf
        skipped = 0
        try:
            for _t, raw in self._raw(topic):
                try:
                    stamp = self._raw_header_stamp(raw, topic)
                except (struct.error, IndexError) as err:
                    raise InputError(self.path, f"message too short for a header: {err}", topic=topic) from err
                if stamp <= last:
                    skipped += 1
                    continue
                if stamp - last < min_interval_s:
                    continue
                m = self._decode(raw, topic)
                try:
                    sweep = decode_cloud(m, _stamp(m))
                except CloudFormatError as err:
                    raise InputError(self.path, str(err), topic=topic) from err
                last = stamp
                yield sweep
        finally:
            if skipped:
                self._note(topic, f"{skipped} sweep(s) skipped: header stamp not after the previous sweep")

    def _screen(self, topic: str, checks: dict[str, Mask]) -> Mask:
        """The validation policy (io/validate.py): mask of valid samples; a note when some
        were dropped; InputError when too many are bad."""
        valid, note = screen(str(self.path), topic, checks, self.cfg.validation)
        if note:
            self._note(topic, note)
        return valid

    def health_notes(self) -> list[str]:
        """One line per problem found in the streams read so far (dropped samples, sorted or
        duplicate stamps, skipped sweeps), for a result's warnings."""
        out = []
        for topic, h in sorted(self._health.items()):
            if h.out_of_order:
                out.append(f"{topic}: {h.out_of_order} out-of-order stamp(s) in the log (sorted when read)")
            if h.duplicates:
                out.append(f"{topic}: {h.duplicates} duplicate stamp(s) dropped")
            out += [f"{topic}: {n}" for n in h.notes]
        return out

    def _set_health(self, health: StreamHealth) -> None:
        """Store a stream's counts, keeping notes made while reading it earlier."""
        old = self._health.get(health.topic)
        self._health[health.topic] = replace(health, notes=old.notes) if old and old.notes else health

    def _note(self, topic: str, note: str) -> None:
        base = self._health.get(topic) or StreamHealth(topic=topic, count=0)
        self._health[topic] = replace(base, notes=(*base.notes, note))

    def stamps(self, topic: str) -> np.ndarray:
        """Header stamps (s) of a topic in log order, as recorded (record times for types
        without a header); from the one scan of the log, so free after `topics`."""
        self._channel(topic)
        if self._stats is None:
            self._scan()
        return self._stamps[topic].copy()

    def sweep_stamps(self, topic: str | None = None) -> np.ndarray:
        return self.stamps(self._topic_for("lidar", topic))

    def gnss(self, topic: str | None = None) -> GnssSeries:
        topic = self._topic_for("gnss", topic)
        t, lla, cov, no_fix, unknown_cov, frame = [], [], [], 0, 0, ""
        for m in self._messages(topic, ("sensor_msgs/msg/NavSatFix",)):
            if m.status.status < 0 or not np.isfinite([m.latitude, m.longitude, m.altitude]).all():
                no_fix += 1
                continue
            t.append(_stamp(m))
            lla.append((m.latitude, m.longitude, m.altitude))
            c = np.asarray(m.position_covariance, float).reshape(3, 3)
            if m.position_covariance_type == 0 or not np.any(np.diag(c) > 0):  # COVARIANCE_TYPE_UNKNOWN
                c = np.diag(self.cfg.gnss_unknown_variance_m2).astype(float)
                unknown_cov += 1
            cov.append(c)
            frame = m.header.frame_id
        if not t:
            raise NoGnssFix(self.path, f"no valid GNSS fix ({no_fix} without fix)", topic=topic)
        valid = self._screen(topic, {"impossible latitude/longitude/altitude":
                                     bad_lat_lon(np.asarray(lla), self.cfg.validation.max_abs_altitude_m)})
        t_a, lla_a, cov_a = np.asarray(t)[valid], np.asarray(lla)[valid], np.asarray(cov)[valid]
        keep, health = _sort_dedup(t_a, topic)
        self._set_health(health)
        if unknown_cov:
            self._note(topic, f"{unknown_cov} fix(es) without covariance: variance "
                       f"{self.cfg.gnss_unknown_variance_m2} m^2 assumed (io.gnss_unknown_variance_m2)")
        lla_a = lla_a[keep]
        origin = np.asarray(self.cfg.gnss_origin_lla if self.cfg.gnss_origin_lla is not None else lla_a[0], float)
        return GnssSeries(t_a[keep], lla_a, geodesy.lla_to_enu(lla_a, origin), cov_a[keep],
                          origin, n_no_fix=no_fix, frame_id=frame)

    def _joint_pair(self, role: str, topic: str | None, scale: float, unit: str,
                    exclude: str | None) -> SidePair:
        topic = self._topic_for(role, topic)
        t, left, right = [], [], []
        for m in self._messages(topic, ("sensor_msgs/msg/JointState",)):
            names = [n.lower() for n in m.name]
            usable = [i for i, n in enumerate(names) if exclude is None or exclude not in n]
            idx_l = next((i for i in usable if "left" in names[i]), None)
            idx_r = next((i for i in usable if "right" in names[i]), None)
            if idx_l is None or idx_r is None or len(m.velocity) <= max(idx_l, idx_r):
                raise InputError(self.path, f"JointState needs left/right joints with velocities, got {list(m.name)}",
                                 topic=topic)
            t.append(_stamp(m))
            left.append(m.velocity[idx_l])
            right.append(m.velocity[idx_r])
        if not t:
            raise InputError(self.path, "topic has no messages", topic=topic)
        lr = np.c_[np.asarray(left, float), np.asarray(right, float)] * scale
        checks = {"non-finite": non_finite(lr)}
        if unit == "m/s":
            checks["speed out of range"] = beyond(lr, self.cfg.validation.max_abs_speed_mps)
        valid = self._screen(topic, checks)
        t_a, lr = np.asarray(t)[valid], lr[valid]
        keep, health = _sort_dedup(t_a, topic)
        self._set_health(health)
        return SidePair(t_a[keep], lr[keep, 0], lr[keep, 1], unit)

    def wheel_speeds(self, topic: str | None = None, wheel_radius_m: float = 0.35) -> SidePair:
        """Wheel surface speeds (m/s) from JointState angular velocities (rad/s)."""
        return self._joint_pair("wheel_speeds", topic, wheel_radius_m, "m/s", exclude="pump")

    def commands(self, topic: str | None = None) -> SidePair:
        """Per-side pump commands (RPM) from JointState velocities."""
        return self._joint_pair("commands", topic, 1.0, "RPM", exclude=None)

    def cmd_vel(self, topic: str | None = None) -> Twists:
        topic = self._topic_for("cmd_vel", topic)
        t, v, w = [], [], []
        for t_rec, m in self._timed_messages(topic, ("geometry_msgs/msg/TwistStamped", "geometry_msgs/msg/Twist")):
            tw = m.twist if hasattr(m, "twist") else m
            t.append(_stamp(m) if hasattr(m, "header") else t_rec)  # plain Twist: record time
            v.append(tw.linear.x)
            w.append(tw.angular.z)
        return self._twists(topic, t, v, w)

    def odometry_twist(self, topic: str | None = None) -> Twists:
        """The body twist of an Odometry topic (default: the wheel odometry): forward speed m/s and
        yaw rate rad/s, in its child frame (nav_msgs/Odometry's convention)."""
        topic = self._topic_for("wheel_odom", topic)
        t, v, w = [], [], []
        for m in self._messages(topic, ("nav_msgs/msg/Odometry",)):
            t.append(_stamp(m))
            v.append(m.twist.twist.linear.x)
            w.append(m.twist.twist.angular.z)
        return self._twists(topic, t, v, w)

    def _twists(self, topic: str, t: list[float], v: list[float], w: list[float]) -> Twists:
        """Screened, sorted twists (non-finite or implausible speeds dropped and reported)."""
        if not t:
            raise InputError(self.path, "topic has no messages", topic=topic)
        vw = np.c_[np.asarray(v, float), np.asarray(w, float)]
        valid = self._screen(topic, {"non-finite": non_finite(vw),
                                     "speed out of range": beyond(vw[:, :1], self.cfg.validation.max_abs_speed_mps)})
        t_a, vw = np.asarray(t)[valid], vw[valid]
        keep, health = _sort_dedup(t_a, topic)
        self._set_health(health)
        return Twists(t_a[keep], vw[keep, 0], vw[keep, 1])

    def waypoints(self, topic: str | None = None) -> Waypoints:
        topic = self._topic_for("path", topic)
        last = None
        for m in self._messages(topic, ("nav_msgs/msg/Path",)):
            last = m
        if last is None or not len(last.poses):
            raise InputError(self.path, "path topic has no poses", topic=topic)
        xy = np.asarray([(p.pose.position.x, p.pose.position.y) for p in last.poses], float)
        xy = xy[self._screen(topic, {"non-finite waypoint": non_finite(xy)})]
        return Waypoints(xy, _stamp(last), last.header.frame_id)

    def trajectory(self, topic: str) -> Trajectory:
        """Poses of a PoseStamped / PoseWithCovarianceStamped / Odometry / TransformStamped topic,
        or of a TF child frame given as "/tf:parent.child"."""
        if topic.startswith("/tf:") or topic.startswith("/tf_static:"):
            return self._tf_trajectory(topic)
        msgtype = self._msgtype(topic)
        t, p, q, frame, child = [], [], [], "", ""
        for m in self._messages(topic):
            if msgtype == "nav_msgs/msg/Odometry":
                pose, child = m.pose.pose, m.child_frame_id
            elif msgtype == "geometry_msgs/msg/PoseWithCovarianceStamped":
                pose = m.pose.pose
            elif msgtype == "geometry_msgs/msg/PoseStamped":
                pose = m.pose
            elif msgtype == "geometry_msgs/msg/TransformStamped":
                tr = m.transform
                pose = type("P", (), {"position": tr.translation, "orientation": tr.rotation})
                child = m.child_frame_id
            else:
                raise InputError(self.path, f"{msgtype} is not a pose type (PoseStamped, Odometry, ...)", topic=topic)
            t.append(_stamp(m))
            p.append((pose.position.x, pose.position.y, pose.position.z))
            o = pose.orientation
            q.append((o.x, o.y, o.z, o.w))
            frame = m.header.frame_id
        if not t:
            raise InputError(self.path, "pose topic has no messages", topic=topic)
        t_a, p_a, q_a = self._valid_poses(topic, t, p, q)
        keep, health = _sort_dedup(t_a, topic)
        self._set_health(health)
        return Trajectory(t_a[keep], p_a[keep], q_a[keep], name=topic, frame_id=frame, child_frame_id=child)

    def _valid_poses(self, topic: str, t: Sequence[float] | np.ndarray,
                     p: Sequence[tuple[float, float, float]] | np.ndarray,
                     q: Sequence[tuple[float, float, float, float]] | np.ndarray,
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Poses with finite, plausible positions and unit quaternions (normalised)."""
        p_a, q_a = np.asarray(p, float).reshape(-1, 3), np.asarray(q, float).reshape(-1, 4)
        v = self.cfg.validation
        valid = self._screen(topic, {"non-finite position": non_finite(p_a),
                                     "position out of range": beyond(p_a, v.max_abs_position_m),
                                     "orientation not a unit quaternion": bad_quaternions(q_a, v.quat_norm_tolerance)})
        return np.asarray(t, float)[valid], p_a[valid], normalised(q_a[valid])

    def _tf_trajectory(self, spec: str) -> Trajectory:
        """`child` in `parent` through the TF tree (/tf and /tf_static), as tf2 looks it up."""
        from mrnc_eval.io.tf_chain import chain_trajectory, edges_from_messages

        tf_topic, _, frames = spec.partition(":")
        parent, _, child = frames.partition(".")
        if not parent or not child:
            raise InputError(self.path, f"TF spec {spec!r} must be /tf:parent.child")
        tf_types = ("tf2_msgs/msg/TFMessage",)
        static_topic = self.roles.get("tf_static")
        static = self._messages(static_topic, tf_types) if static_topic and static_topic != tf_topic else ()
        edges = edges_from_messages(self._messages(tf_topic, tf_types), static)
        traj = chain_trajectory(edges, parent, child, where=self.path, name=spec)
        t_a, p_a, q_a = self._valid_poses(tf_topic, traj.stamps, traj.positions, traj.quat_xyzw)
        return Trajectory(t_a, p_a, q_a, name=spec, frame_id=parent, child_frame_id=child)

    def ground_truth(self, topic: str | None = None) -> Trajectory:
        return self.trajectory(self._topic_for("ground_truth", topic))

    def wheel_odometry(self, topic: str | None = None) -> Trajectory:
        return self.trajectory(self._topic_for("wheel_odom", topic))

    def static_transforms(self) -> dict[tuple[str, str], np.ndarray]:
        topic = self.roles.get("tf_static")
        out: dict[tuple[str, str], np.ndarray] = {}
        if topic is None:
            return out
        for m in self._messages(topic, ("tf2_msgs/msg/TFMessage",)):
            for tr in m.transforms:
                v, r = tr.transform.translation, tr.transform.rotation
                q = np.array([r.x, r.y, r.z, r.w], float)
                xyz = np.array([[v.x, v.y, v.z]], float)
                if bad_quaternions(q, self.cfg.validation.quat_norm_tolerance)[0] or non_finite(xyz)[0]:
                    raise InputError(self.path, f"static transform {tr.header.frame_id} -> {tr.child_frame_id}: "
                                     f"translation {v.x, v.y, v.z} / rotation {tuple(q)} is not finite or not a "
                                     "unit quaternion", topic=topic)
                mat = np.eye(4)
                mat[:3, :3] = _quat_to_matrix(q)
                mat[:3, 3] = (v.x, v.y, v.z)
                out[(tr.header.frame_id.lstrip("/"), tr.child_frame_id.lstrip("/"))] = mat
        return out

    def transform(self, parent: str, child: str) -> np.ndarray:
        """Pose of `child` in `parent` (4x4), composed along the static TF tree."""
        edges: dict[str, list[tuple[str, np.ndarray]]] = {}
        for (a, b), mat in self.static_transforms().items():
            edges.setdefault(a, []).append((b, mat))
            edges.setdefault(b, []).append((a, np.linalg.inv(mat)))
        frontier, seen = [(parent, np.eye(4))], {parent}
        while frontier:
            frame, acc = frontier.pop()
            if frame == child:
                return acc
            for nxt, mat in edges.get(frame, []):
                if nxt not in seen:
                    seen.add(nxt)
                    frontier.append((nxt, acc @ mat))
        raise InputError(self.path, f"no static transform from {parent!r} to {child!r}", topic="/tf_static")

    def strings(self, topic: str) -> list[str]:
        return [str(m.data) for m in self._messages(topic, ("std_msgs/msg/String",))]


def _expand(path: str | Path) -> list[Path]:
    """A path, or a glob pattern for split ROS 1 bags (sorted, so split order is kept)."""
    text = str(path)
    split = split_log_paths(text)  # "run_0.mcap,run_1.mcap": one recording in several files
    if split is not None:
        return [p for part in split for p in _expand(part)]
    if Path(text).name == "metadata.yaml":  # a ROS 2 bag given by its metadata file
        return [Path(text).parent]
    if not Path(text).exists() and any(ch in text for ch in "*?["):
        matches = sorted(glob.glob(text))
        if not matches:
            raise InputError(text, "no file matches this pattern")
        return [Path(m) for m in matches]
    return [Path(text)]


def open_log(path: str | Path | list[str | Path], io_cfg: IoConfig | None = None) -> LogReader:
    """Open a log: a file, a ROS 2 bag directory, or a recording split into several files of
    one kind (a list, "a.bag,b.bag", or a glob pattern such as "run_*.bag"); raises
    InputError on anything unreadable."""
    items = list(path) if isinstance(path, (list, tuple)) else [path]
    paths = [p for item in items for p in _expand(item)]
    if not paths:
        raise InputError("<none>", "no log given")
    return LogReader(paths, io_cfg)
