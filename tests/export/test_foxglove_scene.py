"""`export --with-log` draws one coherent scene: every frame any message uses hangs in one TF tree
(our /eval/tf plus the log's own /tf_static), and composing the transforms puts the log's
/ground_truth on /eval/ground_truth and the SLAM estimate on the ground truth, in the viewer's
fixed frame. The file is read back with the mcap library and rosbags' CDR decoder, not our writer."""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mrnc_eval.cli import main
from mrnc_eval.results import read_result
from tests.export.conftest import Runs

Edge = tuple[float, np.ndarray]  # (stamp s, 4x4 child in parent)


def _matrix(t: dict, q: dict) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat([q["x"], q["y"], q["z"], q["w"]]).as_matrix()
    m[:3, 3] = [t["x"], t["y"], t["z"]]
    return m


def _stamp(ts: dict) -> float:
    return ts["sec"] + ts["nsec"] * 1e-9


class Scene:
    """Edges (parent of each child, transforms over time) and every frame_id a message uses."""

    def __init__(self) -> None:
        self.parents: dict[str, set[str]] = defaultdict(set)
        self.edges: dict[str, list[Edge]] = defaultdict(list)
        self.used: dict[str, set[str]] = defaultdict(set)  # frame -> topics

    def add(self, parent: str, child: str, stamp: float, m: np.ndarray) -> None:
        self.parents[child].add(parent)
        self.edges[child].append((stamp, m))

    def root_of(self, frame: str) -> str:
        seen = []
        while frame in self.parents:
            (parent,) = self.parents[frame]  # exactly one parent: a tree
            assert frame not in seen, f"TF cycle through {frame}"
            seen.append(frame)
            frame = parent
        return frame

    def check_tree(self) -> str:
        """The single root every used frame reaches; AssertionError for two parents or roots."""
        two = {c: p for c, p in self.parents.items() if len(p) > 1}
        assert not two, f"frames with two parents: {two}"
        roots = {f: self.root_of(f) for f in self.used}
        assert len(set(roots.values())) == 1, f"frames in separate trees: {roots}"
        return next(iter(roots.values()))

    def in_root(self, frame: str, t: float) -> np.ndarray:
        """frame's pose in the root at time t: each edge's latest transform at or before t (its
        first one before that, as a viewer holds static-like transforms)."""
        m = np.eye(4)
        while frame in self.parents:
            stamps = np.array([s for s, _ in self.edges[frame]])
            k = max(int(np.searchsorted(stamps, t + 1e-9, side="right")) - 1, 0)
            m = self.edges[frame][k][1] @ m
            (frame,) = self.parents[frame]
        return m


def read_scene(path: Path) -> tuple[Scene, dict[str, list[tuple[float, np.ndarray, str]]]]:
    """The TF tree and, per pose topic, (stamp, 4x4 pose in its frame, frame)."""
    from mcap.reader import make_reader

    from mrnc_eval.io.typestore import typestore_for

    store = typestore_for(ros1=False)
    scene = Scene()
    poses: dict[str, list[tuple[float, np.ndarray, str]]] = defaultdict(list)
    with path.open("rb") as fh:
        for schema, channel, message in make_reader(fh).iter_messages(log_time_order=True):
            if channel.message_encoding == "json":
                body = json.loads(message.data)
                if schema.name == "foxglove.FrameTransform":
                    scene.add(body["parent_frame_id"], body["child_frame_id"], _stamp(body["timestamp"]),
                              _matrix(body["translation"], body["rotation"]))
                    continue
                entities = body.get("entities", [body])
                for frame in {e["frame_id"] for e in entities if e.get("frame_id")}:
                    scene.used[frame].add(channel.topic)
                if schema.name == "foxglove.PoseInFrame":
                    p = body["pose"]
                    poses[channel.topic].append((_stamp(body["timestamp"]), _matrix(p["position"], p["orientation"]),
                                                 body["frame_id"]))
                continue
            msg = store.deserialize_cdr(message.data, schema.name)
            if schema.name == "tf2_msgs/msg/TFMessage":
                for tf in msg.transforms:
                    s = tf.header.stamp.sec + tf.header.stamp.nanosec * 1e-9
                    scene.add(tf.header.frame_id, tf.child_frame_id, s,
                              _matrix(vars(tf.transform.translation), vars(tf.transform.rotation)))
                continue
            header = getattr(msg, "header", None)
            if header is not None and header.frame_id:
                scene.used[header.frame_id].add(channel.topic)
            if schema.name == "nav_msgs/msg/Odometry":
                p = msg.pose.pose
                poses[channel.topic].append((header.stamp.sec + header.stamp.nanosec * 1e-9,
                                             _matrix(vars(p.position), vars(p.orientation)), header.frame_id))
    return scene, poses


@pytest.fixture(scope="module")
def scene(sim_runs: Runs, tmp_path_factory: pytest.TempPathFactory):
    out = tmp_path_factory.mktemp("scene") / "scene.mcap"
    assert main(["export", str(sim_runs.root), "--mcap", str(out), "--with-log"]) == 0
    return read_scene(out)


def test_every_frame_hangs_in_one_tree_rooted_in_the_ground_truths_frame(scene) -> None:
    tree, _poses = scene
    assert tree.check_tree() == "map"  # the frame the log's /ground_truth declares
    # the log's sensor frames are placed through base_link, which the SLAM pose moves
    for frame in ("os_sensor", "os_imu", "gnss", "base_link", "lio/map", "odom"):
        assert frame in tree.used or frame in tree.parents, frame
        assert tree.root_of(frame) == "map", frame
    assert tree.parents["base_link"] == {"lio/map"}
    assert tree.parents["lio/map"] == {"map"}
    (_t, align), = tree.edges["lio/map"]
    assert align[2, 2] > np.cos(np.radians(0.01))  # gravity-aligned frames: the alignment turns about z only


def test_the_logs_ground_truth_and_ours_coincide_in_the_fixed_frame(scene) -> None:
    tree, poses = scene
    ours = {round(t, 6): tree.in_root(f, t) @ m for t, m, f in poses["/eval/ground_truth/pose"]}
    theirs = [(t, tree.in_root(f, t) @ m) for t, m, f in poses["/ground_truth"]]
    assert len(theirs) == len(ours) > 100
    for t, m in theirs:
        np.testing.assert_allclose(ours[round(t, 6)], m, atol=1e-9)


def test_the_estimate_lands_on_the_ground_truth_and_the_odometry_on_the_robot(scene, sim_runs: Runs) -> None:
    """Composed into the fixed frame the SLAM poses lie on the ground truth within its APE; the
    odom frame puts the log's /wheel_odom on the SLAM pose at the SLAM stamps."""
    tree, poses = scene
    gt = {round(t, 6): tree.in_root(f, t) @ m for t, m, f in poses["/eval/ground_truth/pose"]}
    gt_t = np.array(sorted(gt))
    errors = []
    for t, m, frame in poses["/eval/slam/lio/pose"]:
        near = gt_t[np.argmin(np.abs(gt_t - t))]
        if abs(near - t) < 0.006:
            errors.append(np.linalg.norm((tree.in_root(frame, t) @ m)[:3, 3] - gt[near][:3, 3]))
    ape = read_result(sim_runs.slam).metric("ape_rmse_m")
    assert ape is not None
    assert len(errors) > 10
    assert np.sqrt(np.mean(np.square(errors))) < 2 * ape.value + 0.01
    body = {round(t, 6): tree.in_root("base_link", t) for t, _m, _f in poses["/eval/slam/lio/pose"]}
    odom_t = np.array([t for t, _m, _f in poses["/wheel_odom"]])
    checked = 0
    for t, m in body.items():
        k = int(np.argmin(np.abs(odom_t - t)))
        if abs(odom_t[k] - t) < 1e-6:
            _t, o, frame = poses["/wheel_odom"][k]
            np.testing.assert_allclose(tree.in_root(frame, t) @ o, m, atol=1e-6)
            checked += 1
    assert checked > 10


def test_the_tree_check_fails_on_two_roots_and_two_parents() -> None:
    """Negative control: the old export (estimate in map, ground truth in an unlinked world) fails."""
    old = Scene()
    old.used.update({"map": {"/eval/slam/lio/pose"}, "world": {"/eval/ground_truth/pose"}})
    with pytest.raises(AssertionError, match="separate trees"):
        old.check_tree()
    twice = Scene()
    twice.add("map", "base_link", 0.0, np.eye(4))
    twice.add("odom", "base_link", 0.0, np.eye(4))
    twice.used["base_link"].add("/x")
    with pytest.raises(AssertionError, match="two parents"):
        twice.check_tree()
