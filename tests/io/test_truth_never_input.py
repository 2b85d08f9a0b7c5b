"""Inputs never come from ground truth (io/roles.py rule 4): a topic that is the run's ground-truth
source, or whose name marks it as truth, never gets an input role; `info` says why; the SLAM's
result.json lists every topic it used as input with its role."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mrnc_eval.cli import main
from mrnc_eval.errors import ConfigError
from mrnc_eval.io import open_log
from mrnc_eval.io.config import IoConfig
from mrnc_eval.io.roles import Candidate, TruthExclusion, candidates_by_role, choose_roles, truth_marker

SAMPLE = Path(__file__).resolve().parents[2] / "sample_logs" / "loop_forest.bag"
ODOM = "nav_msgs/msg/Odometry"


def _rewrite(dest: Path, rename: dict[str, str], drop: set[str], seconds: float) -> Path:
    """The ROS 1 sample's first `seconds` with topics renamed and some dropped (raw bytes copied)."""
    from rosbags.rosbag1 import Reader, Writer

    if not SAMPLE.exists():
        pytest.fail(f"sample log missing: {SAMPLE}")
    with Reader(SAMPLE) as reader, Writer(dest) as writer:
        out = {c.id: writer.add_connection(rename.get(c.topic, c.topic), c.msgtype, msgdef=c.msgdef.data,
                                           md5sum=c.digest)
               for c in reader.connections if c.topic not in drop}
        end = reader.start_time + int(seconds * 1e9)
        for conn, stamp, raw in reader.messages():
            if conn.id in out and stamp <= end:
                writer.write(out[conn.id], stamp, raw)
    return dest


@pytest.fixture(scope="module")
def truth_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _rewrite(tmp_path_factory.mktemp("truth") / "truth.bag", {"/ground_truth": "/truth/odom"},
                    {"/wheel_odom"}, 8.0)


@pytest.fixture(scope="module")
def plain_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Negative control: the same ground truth under a name that does not say so."""
    return _rewrite(tmp_path_factory.mktemp("plain") / "plain.bag", {"/ground_truth": "/robot/odom"},
                    {"/wheel_odom"}, 8.0)


@pytest.mark.parametrize("topic", ["/ground_truth", "/truth/odom", "/odom_gt", "/gt/pose", "/vicon/robot/robot",
                                   "/mocap_node/pose", "/optitrack/rigid_body_1", "/sim/groundtruth",
                                   "/Ground-Truth/odom"])
def test_truth_names_are_recognised(topic: str) -> None:
    assert truth_marker(topic) is not None


@pytest.mark.parametrize("topic", ["/wheel_odom", "/odometry/filtered", "/ouster/imu", "/gtsam_odom", "/right/odom",
                                   "/construct/odom", "/gnss/fix"])
def test_ordinary_names_are_not_truth(topic: str) -> None:
    assert truth_marker(topic) is None


def test_a_truth_named_odometry_is_ground_truth_and_never_wheel_odometry() -> None:
    found = candidates_by_role([Candidate("/truth/odom", ODOM, 100), Candidate("/mocap/imu", "sensor_msgs/msg/Imu", 50),
                                Candidate("/ouster/imu", "sensor_msgs/msg/Imu", 10)], {})
    roles, notes = choose_roles(found, {})
    assert roles["ground_truth"] == "/truth/odom"
    assert "wheel_odom" not in roles
    assert roles["imu"] == "/ouster/imu"  # the mocap IMU has more messages but is truth
    excluded = [n for n in notes if isinstance(n, TruthExclusion)]
    assert [(n.role, n.topic) for n in excluded] == [("wheel_odom", "/truth/odom")]
    assert "ground truth" in excluded[0].message()
    # negative control: under an ordinary name the same topic is the wheel odometry
    roles, notes = choose_roles(candidates_by_role([Candidate("/robot/odom", ODOM, 100)], {}), {})
    assert roles.get("wheel_odom") == "/robot/odom"
    assert not any(isinstance(n, TruthExclusion) for n in notes)


def test_the_ground_truth_source_is_never_an_input_even_with_an_ordinary_name() -> None:
    found = candidates_by_role([Candidate("/odom", ODOM, 100), Candidate("/wheel_odom", ODOM, 50)], {})
    roles, _ = choose_roles(found, {"ground_truth": "/odom"})
    assert roles["ground_truth"] == "/odom"
    assert roles["wheel_odom"] == "/wheel_odom"
    roles, notes = choose_roles(candidates_by_role([Candidate("/odom", ODOM, 100)], {}), {"ground_truth": "/odom"})
    assert "wheel_odom" not in roles
    assert any(isinstance(n, TruthExclusion) and "ground-truth source" in n.reason for n in notes)


def test_an_override_naming_truth_as_an_input_is_refused() -> None:
    found = candidates_by_role([Candidate("/truth/odom", ODOM, 100)], {})
    with pytest.raises(ConfigError, match="ground truth"):
        choose_roles(found, {"wheel_odom": "/truth/odom"})


def test_the_log_reader_and_info_keep_the_truth_out(truth_bag: Path, plain_bag: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    with open_log(truth_bag, IoConfig()) as lg:
        assert lg.roles["ground_truth"] == "/truth/odom"
        assert "wheel_odom" not in lg.roles
    with open_log(plain_bag, IoConfig()) as lg:  # negative control
        assert lg.roles["wheel_odom"] == "/robot/odom"
    assert main(["info", str(truth_bag)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "/truth/odom is not used as wheel odometry" in out
    assert "'truth'" in out


def test_the_slam_result_lists_its_inputs_and_never_the_truth(truth_bag: Path, plain_bag: Path,
                                                              tmp_path: Path) -> None:
    used = {}
    for name, log in (("truth", truth_bag), ("plain", plain_bag)):
        out = tmp_path / name
        assert main(["slam", str(log), "--out", str(out), "--no-loop", "--set", "slam.map_quality.enabled=false"]) == 0
        result = json.loads((out / "latest" / "result.json").read_text())
        used[name] = result["extra"]["inputs"]
    assert used["truth"] == {"lidar": "/ouster/points", "imu": "/ouster/imu", "gnss": "/gnss/fix"}
    assert used["plain"]["wheel_odom"] == "/robot/odom"  # negative control: the rule is what keeps it out
