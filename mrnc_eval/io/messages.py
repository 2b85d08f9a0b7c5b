"""Build ROS message objects (rosbags typestore classes) from our arrays.

Shared by the writer; one function per message type, ROS 1 and ROS 2 alike (the
typestore decides the wire format).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

# rosbags builds message classes at run time from the typestore: both are dynamic to a type checker.
Typestore = Any
RosMsg = Any

OUSTER_FIELDS = (  # ouster-ros "original" layout, as in shared/data (point_step 48)
    ("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 16, 7), ("t", 20, 6),
    ("reflectivity", 24, 4), ("ring", 26, 4), ("ambient", 28, 4), ("range", 32, 6),
)
OUSTER_POINT_STEP = 48


def stamp_msg(ts: Typestore, t: float, ros1: bool) -> RosMsg:
    sec = int(np.floor(t))
    nsec = int(round((t - sec) * 1e9))
    if nsec >= 1_000_000_000:
        sec, nsec = sec + 1, nsec - 1_000_000_000
    return ts.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)


def header(ts: Typestore, t: float, frame_id: str, ros1: bool, seq: int = 0) -> RosMsg:
    kwargs: dict[str, Any] = {"stamp": stamp_msg(ts, t, ros1), "frame_id": frame_id}
    if ros1:
        kwargs["seq"] = seq
    return ts.types["std_msgs/msg/Header"](**kwargs)


def vector3(ts: Typestore, v: ArrayLike) -> RosMsg:
    v = np.asarray(v, dtype=float)
    return ts.types["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]), z=float(v[2]))


def quaternion(ts: Typestore, q: ArrayLike) -> RosMsg:
    q = np.asarray(q, dtype=float)
    return ts.types["geometry_msgs/msg/Quaternion"](x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))


def point(ts: Typestore, p: ArrayLike) -> RosMsg:
    p = np.asarray(p, dtype=float)
    return ts.types["geometry_msgs/msg/Point"](x=float(p[0]), y=float(p[1]), z=float(p[2]))


def pose(ts: Typestore, p: ArrayLike, q: ArrayLike) -> RosMsg:
    return ts.types["geometry_msgs/msg/Pose"](position=point(ts, p), orientation=quaternion(ts, q))


def imu(ts: Typestore, t: float, frame_id: str, acc: ArrayLike, gyro: ArrayLike, q: ArrayLike | None, ros1: bool,
        seq: int = 0, acc_var: float = 0.01, gyro_var: float = 6e-4) -> RosMsg:
    cov0 = np.zeros(9)
    ocov = cov0.copy()
    if q is None:
        ocov[0] = -1.0  # REP-145: orientation not provided (6-axis IMU)
        q = (0.0, 0.0, 0.0, 0.0) if not ros1 else (0.0, 0.0, 0.0, 1.0)
    return ts.types["sensor_msgs/msg/Imu"](
        header=header(ts, t, frame_id, ros1, seq),
        orientation=quaternion(ts, q),
        orientation_covariance=ocov,
        angular_velocity=vector3(ts, gyro),
        angular_velocity_covariance=np.diag([gyro_var] * 3).ravel(),
        linear_acceleration=vector3(ts, acc),
        linear_acceleration_covariance=np.diag([acc_var] * 3).ravel(),
    )


_NUMPY_OF_DATATYPE = {4: "<u2", 6: "<u4", 7: "<f4"}


def _point_dtype(fields: Sequence[tuple[str, int, int]], point_step: int) -> np.dtype:
    """The numpy record of one point of a PointCloud2 layout: (name, byte offset, PointField datatype)."""
    return np.dtype({"names": [n for n, _, _ in fields], "formats": [_NUMPY_OF_DATATYPE[d] for _, _, d in fields],
                     "offsets": [o for _, o, _ in fields], "itemsize": point_step})


def _pointcloud2(ts: Typestore, t: float, frame_id: str, ros1: bool, seq: int, fields: Sequence[tuple[str, int, int]],
                 rec: np.ndarray, height: int, width: int, is_dense: bool) -> RosMsg:
    """A PointCloud2 of the records `rec` (height x width points of `fields`)."""
    pf = ts.types["sensor_msgs/msg/PointField"]
    step = rec.dtype.itemsize
    return ts.types["sensor_msgs/msg/PointCloud2"](
        header=header(ts, t, frame_id, ros1, seq), height=height, width=width,
        fields=[pf(name=n, offset=o, datatype=d, count=1) for n, o, d in fields], is_bigendian=False,
        point_step=step, row_step=step * width, data=rec.view(np.uint8), is_dense=is_dense,
    )


OUSTER_DTYPE = _point_dtype(OUSTER_FIELDS, OUSTER_POINT_STEP)


RETURNS_FIELDS = (  # the returns only, with the fields a deskewing SLAM reads (LIO-SAM's point type minus
    # reflectivity, noise and range): x y z intensity f32, t u32 ns, ring u16, 2 bytes of padding
    ("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 12, 7), ("t", 16, 6), ("ring", 20, 4),
)
RETURNS_POINT_STEP = 24
RETURNS_DTYPE = _point_dtype(RETURNS_FIELDS, RETURNS_POINT_STEP)


def returns_cloud(ts: Typestore, t: float, frame_id: str, xyz: ArrayLike, t_ns: ArrayLike, intensity: ArrayLike,
                  ring: ArrayLike, ros1: bool, seq: int = 0) -> RosMsg:
    """An unorganised cloud (height 1) of N returns: xyz (N, 3), t_ns, intensity, ring (N,)."""
    xyz = np.asarray(xyz, dtype=np.float32).reshape(-1, 3)
    n = xyz.shape[0]
    rec = np.zeros(n, dtype=RETURNS_DTYPE)  # zeroed: padding bytes are deterministic
    rec["x"], rec["y"], rec["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    rec["intensity"] = np.asarray(intensity).reshape(-1)
    rec["t"] = np.asarray(t_ns).reshape(-1)
    rec["ring"] = np.asarray(ring).reshape(-1)
    return _pointcloud2(ts, t, frame_id, ros1, seq, RETURNS_FIELDS, rec, height=1, width=n, is_dense=True)


def ouster_cloud(ts: Typestore, t: float, frame_id: str, xyz: ArrayLike, t_ns: ArrayLike, range_mm: ArrayLike,
                 reflectivity: ArrayLike, intensity: ArrayLike, ambient: ArrayLike, ros1: bool, seq: int = 0) -> RosMsg:
    h, w = np.shape(t_ns)
    rec = np.zeros(h * w, dtype=OUSTER_DTYPE)  # zeroed: padding bytes are deterministic
    xyz = np.asarray(xyz, dtype=np.float32).reshape(h * w, 3)
    rec["x"], rec["y"], rec["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    rec["intensity"] = np.asarray(intensity).reshape(-1)
    rec["t"] = np.asarray(t_ns).reshape(-1)
    rec["reflectivity"] = np.asarray(reflectivity).reshape(-1)
    rec["ring"] = np.repeat(np.arange(h, dtype=np.uint16), w)
    rec["ambient"] = np.asarray(ambient).reshape(-1)
    rec["range"] = np.asarray(range_mm).reshape(-1)
    return _pointcloud2(ts, t, frame_id, ros1, seq, OUSTER_FIELDS, rec, height=h, width=w, is_dense=False)


def navsatfix(ts: Typestore, t: float, frame_id: str, lla: ArrayLike, cov: ArrayLike, status: int, ros1: bool,
              seq: int = 0) -> RosMsg:
    lla = np.asarray(lla, dtype=float)
    st = ts.types["sensor_msgs/msg/NavSatStatus"](status=int(status), service=1)
    return ts.types["sensor_msgs/msg/NavSatFix"](
        header=header(ts, t, frame_id, ros1, seq), status=st, latitude=float(lla[0]), longitude=float(lla[1]),
        altitude=float(lla[2]), position_covariance=np.asarray(cov, dtype=float).reshape(9),
        position_covariance_type=3,
    )


def joint_state(ts: Typestore, t: float, names: Sequence[str], velocity: ArrayLike, ros1: bool, seq: int = 0) -> RosMsg:
    k = len(names)
    return ts.types["sensor_msgs/msg/JointState"](
        header=header(ts, t, "", ros1, seq), name=list(names), position=np.zeros(k),
        velocity=np.asarray(velocity, dtype=float), effort=np.zeros(k),
    )


def odometry(ts: Typestore, t: float, frame_id: str, child: str, p: ArrayLike, q: ArrayLike, lin: ArrayLike,
             ang: ArrayLike, ros1: bool, seq: int = 0) -> RosMsg:
    cov = np.zeros(36)
    pwc = ts.types["geometry_msgs/msg/PoseWithCovariance"](pose=pose(ts, p, q), covariance=cov)
    tw = ts.types["geometry_msgs/msg/Twist"](linear=vector3(ts, lin), angular=vector3(ts, ang))
    twc = ts.types["geometry_msgs/msg/TwistWithCovariance"](twist=tw, covariance=cov)
    return ts.types["nav_msgs/msg/Odometry"](
        header=header(ts, t, frame_id, ros1, seq), child_frame_id=child, pose=pwc, twist=twc)


def path(ts: Typestore, t: float, frame_id: str, xy: ArrayLike, ros1: bool) -> RosMsg:
    ps = ts.types["geometry_msgs/msg/PoseStamped"]
    poses = [ps(header=header(ts, t, frame_id, ros1, i), pose=pose(ts, (x, y, 0.0), (0.0, 0.0, 0.0, 1.0)))
             for i, (x, y) in enumerate(np.asarray(xy, dtype=float))]
    return ts.types["nav_msgs/msg/Path"](header=header(ts, t, frame_id, ros1), poses=poses)


def twist_stamped(ts: Typestore, t: float, frame_id: str, v: float, omega: float, ros1: bool, seq: int = 0) -> RosMsg:
    tw = ts.types["geometry_msgs/msg/Twist"](linear=vector3(ts, (v, 0, 0)), angular=vector3(ts, (0, 0, omega)))
    return ts.types["geometry_msgs/msg/TwistStamped"](header=header(ts, t, frame_id, ros1, seq), twist=tw)


def tf_message(ts: Typestore, t: float, transforms: Sequence[tuple[str, str, ArrayLike]], ros1: bool) -> RosMsg:
    from mrnc_eval.geometry import rotation

    out = []
    for parent, child, mat in transforms:
        mat = np.asarray(mat, dtype=float)
        q = rotation.matrix_to_quat(mat[:3, :3])
        tr = ts.types["geometry_msgs/msg/Transform"](translation=vector3(ts, mat[:3, 3]), rotation=quaternion(ts, q))
        out.append(ts.types["geometry_msgs/msg/TransformStamped"](
            header=header(ts, t, parent, ros1), child_frame_id=child, transform=tr))
    return ts.types["tf2_msgs/msg/TFMessage"](transforms=out)


def string(ts: Typestore, text: str) -> RosMsg:
    return ts.types["std_msgs/msg/String"](data=text)
