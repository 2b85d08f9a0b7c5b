"""Roles are chosen by io/roles.py's documented rule (name and frame, expected fields, message
count), not alphabetically, and a choice among several candidates is announced with the override."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from mrnc_eval.cli import main
from mrnc_eval.io import open_log
from mrnc_eval.io.config import IoConfig
from mrnc_eval.io.roles import Candidate, choose_roles

SAMPLE = Path(__file__).resolve().parents[2] / "sample_logs" / "loop_forest.bag"


def _copy_with_extra(dest: Path, extra: dict[str, tuple[str, int | None]]) -> Path:
    """The ROS 1 sample plus topics copied from its own: new topic -> (source topic, messages
    to copy, None = all). Raw bytes are copied, so each copy carries the source's fields and frames."""
    from rosbags.rosbag1 import Reader, Writer

    with Reader(SAMPLE) as reader, Writer(dest) as writer:
        out = {c.id: writer.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest)
               for c in reader.connections}
        copies = {}
        for new, (source, _n) in extra.items():
            src = next(c for c in reader.connections if c.topic == source)
            copies[new] = writer.add_connection(new, src.msgtype, msgdef=src.msgdef.data, md5sum=src.digest)
        written = dict.fromkeys(extra, 0)
        for conn, stamp, raw in reader.messages():
            writer.write(out[conn.id], stamp, raw)
            for new, (source, n) in extra.items():
                if conn.topic == source and (n is None or written[new] < n):
                    writer.write(copies[new], stamp, raw)
                    written[new] += 1
    return dest


@pytest.fixture(scope="module")
def crowded_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if not SAMPLE.exists():
        pytest.fail(f"sample log missing: {SAMPLE}")
    # /camera/depth/points sorts before /ouster/points, /odometry/filtered before /wheel_odom:
    # the alphabetical rule gave both roles to the wrong topic
    extra: dict[str, tuple[str, int | None]] = {"/camera/depth/points": ("/ouster/points", 3),
                                                "/odometry/filtered": ("/wheel_odom", None)}
    return _copy_with_extra(tmp_path_factory.mktemp("roles") / "crowded.bag", extra)


def test_the_lidar_and_wheel_odometry_keep_their_topics_with_a_warning(crowded_bag: Path,
                                                                       caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.WARNING), open_log(crowded_bag) as lg:
        roles = lg.roles
        doubts = {d.role: d for d in lg.role_doubts}
    assert roles["lidar"] == "/ouster/points"
    assert roles["wheel_odom"] == "/wheel_odom"
    assert doubts["lidar"].alternatives == ("/camera/depth/points",)
    assert doubts["wheel_odom"].alternatives == ("/odometry/filtered",)
    text = caplog.text
    assert "--set io.roles.lidar=TOPIC" in text
    assert "/camera/depth/points" in text
    assert "--set io.roles.wheel_odom=TOPIC" in text


def test_an_override_wins_and_silences_the_warning(crowded_bag: Path, caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.WARNING), \
            open_log(crowded_bag, IoConfig(roles={"lidar": "/camera/depth/points"})) as lg:
        assert lg.roles["lidar"] == "/camera/depth/points"
        assert "lidar" not in {d.role for d in lg.role_doubts}
    assert "io.roles.lidar" not in caplog.text


def test_info_lists_the_choice_as_a_finding(crowded_bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", str(crowded_bag)]) == 0
    out = " ".join(capsys.readouterr().out.split())  # rich wraps long findings
    assert "role lidar: using /ouster/points" in out
    assert "--set io.roles.lidar=TOPIC" in out


def test_the_sample_alone_has_no_doubt() -> None:
    with open_log(SAMPLE) as lg:
        assert lg.role_doubts == []
        assert lg.roles["lidar"] == "/ouster/points"


def test_rule_order_name_then_fields_then_count() -> None:
    cloud = "sensor_msgs/msg/PointCloud2"
    odom = "nav_msgs/msg/Odometry"

    def pick(*cands: Candidate) -> str:
        found = {"lidar" if c.msgtype == cloud else "wheel_odom": list(cands) for c in cands[:1]}
        return next(iter(choose_roles(found, {})[0].values()))

    # a camera topic loses although it has more messages
    assert pick(Candidate("/a/camera/points", cloud, 900), Candidate("/b/points", cloud, 10)) == "/b/points"
    # ring + per-point time beat a bare xyz cloud with more messages
    assert pick(Candidate("/a", cloud, 900, ("x", "y", "z")),
                Candidate("/b", cloud, 10, ("x", "y", "z", "t", "ring"))) == "/b"
    # otherwise the busier topic
    assert pick(Candidate("/a", cloud, 10), Candidate("/b", cloud, 900)) == "/b"
    # an odometry in an odom frame beats one in map; a fused one loses whatever its frame
    assert pick(Candidate("/a", odom, 50, frame_id="map"), Candidate("/b", odom, 50, frame_id="odom")) == "/b"
    assert pick(Candidate("/ekf/odom", odom, 99, frame_id="odom"), Candidate("/b", odom, 50)) == "/b"
