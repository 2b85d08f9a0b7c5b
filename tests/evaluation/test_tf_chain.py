"""`log:/tf:PARENT.CHILD` through intermediate frames, on a ROS 1 bag written with rosbags'
writer: odom -> base_footprint (dynamic, 50 Hz) -> base_link (static) -> imu_link (dynamic,
20 Hz). Each transform is a known function of time, so the composed pose has a closed form."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mrnc_eval.errors import InputError
from mrnc_eval.io.messages import tf_message
from mrnc_eval.io.trajectory_files import read_trajectory
from mrnc_eval.io.typestore import typestore_for

FOOTPRINT_TO_LINK = np.array([[1, 0, 0, 0.1], [0, 1, 0, 0.0], [0, 0, 1, 0.3], [0, 0, 0, 1.0]])


def odom_to_footprint(t: np.ndarray) -> np.ndarray:
    """Driving a circle of 5 m radius at 0.2 rad/s, heading along the path."""
    a = 0.2 * t
    m = np.tile(np.eye(4), (t.size, 1, 1))
    m[:, :3, :3] = Rotation.from_euler("z", (a + np.pi / 2)[:, None]).as_matrix()
    m[:, 0, 3], m[:, 1, 3] = 5 * np.cos(a), 5 * np.sin(a)
    return m


def link_to_imu(t: np.ndarray) -> np.ndarray:
    """A mount turning at a constant rate about a fixed axis and sliding linearly: slerp and
    linear interpolation between its 20 Hz samples are exact."""
    m = np.tile(np.eye(4), (t.size, 1, 1))
    m[:, :3, :3] = Rotation.from_rotvec(np.outer(0.05 * t, [0.0, 0.6, 0.8])).as_matrix()
    m[:, :3, 3] = np.c_[0.2 + 0.01 * t, -0.05 * np.ones_like(t), 0.02 * t]
    return m


def _write_bag(path: Path) -> Path:
    from rosbags.rosbag1 import Writer

    ts = typestore_for(ros1=True)
    fast, slow = np.arange(0.0, 10.0, 0.02) + 100.0, np.arange(0.0, 10.0001, 0.05) + 100.0
    msgs = [(t, "/tf", tf_message(ts, t, [("odom", "base_footprint", m)], True))
            for t, m in zip(fast, odom_to_footprint(fast - 100.0), strict=True)]
    msgs += [(t, "/tf", tf_message(ts, t, [("base_link", "imu_link", m)], True))
             for t, m in zip(slow, link_to_imu(slow - 100.0), strict=True)]
    static = tf_message(ts, 100.0, [("base_footprint", "base_link", FOOTPRINT_TO_LINK),
                                    ("map", "world", np.eye(4))], True)
    with Writer(path) as writer:
        tf = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=ts)
        tf_static = writer.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=ts, latching=1)
        writer.write(tf_static, int(100e9), bytes(ts.serialize_ros1(static, "tf2_msgs/msg/TFMessage")))
        for t, _, msg in sorted(msgs, key=lambda x: x[0]):
            writer.write(tf, int(round(t * 1e9)), bytes(ts.serialize_ros1(msg, "tf2_msgs/msg/TFMessage")))
    return path


@pytest.fixture(scope="module")
def tf_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _write_bag(tmp_path_factory.mktemp("tf") / "robot.bag")


def _assert_poses(traj, expected: np.ndarray) -> None:
    np.testing.assert_allclose(traj.positions, expected[:, :3, 3], atol=1e-9)
    got = Rotation.from_quat(traj.quat_xyzw)
    angle = (got.inv() * Rotation.from_matrix(expected[:, :3, :3])).magnitude()
    assert angle.max() < 1e-9


def test_chain_through_static_and_dynamic_edges(tf_bag: Path) -> None:
    traj = read_trajectory(f"{tf_bag}:/tf:odom.imu_link")
    # the stamps of the fastest dynamic edge (50 Hz), inside the time both dynamic edges cover
    assert len(traj) == 500
    assert traj.stamps[0] == pytest.approx(100.0)
    assert traj.stamps[-1] == pytest.approx(109.98)
    t = traj.stamps - 100.0
    expected = odom_to_footprint(t) @ FOOTPRINT_TO_LINK @ link_to_imu(t)
    _assert_poses(traj, expected)
    assert (traj.frame_id, traj.child_frame_id) == ("odom", "imu_link")


def test_chain_against_edge_direction_and_two_hops(tf_bag: Path) -> None:
    link = read_trajectory(f"{tf_bag}:/tf:odom.base_link")  # the ground-robot case of issue 14
    _assert_poses(link, odom_to_footprint(link.stamps - 100.0) @ FOOTPRINT_TO_LINK)
    back = read_trajectory(f"{tf_bag}:/tf:base_link.odom")
    _assert_poses(back, np.linalg.inv(odom_to_footprint(back.stamps - 100.0) @ FOOTPRINT_TO_LINK))


def test_missing_link_names_both_trees(tf_bag: Path) -> None:
    with pytest.raises(InputError, match=r"no TF chain from 'odom' to 'world'.*'odom' connects only "
                                         r"base_footprint, base_link, imu_link, odom and 'world' only map, world"):
        read_trajectory(f"{tf_bag}:/tf:odom.world")
    with pytest.raises(InputError, match="frame 'camera' is not in the TF tree"):
        read_trajectory(f"{tf_bag}:/tf:odom.camera")
    with pytest.raises(InputError, match="only static transforms"):
        read_trajectory(f"{tf_bag}:/tf:base_footprint.base_link")
