"""`mrnc-eval export --mcap`: the file read back with the mcap library (independent of our writer)."""

from __future__ import annotations

import json
import os
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.cli import main
from mrnc_eval.io import open_log
from mrnc_eval.io.trajectory_files import read_tum
from mrnc_eval.results import read_result
from tests.export.conftest import Runs

FOXGLOVE = {"foxglove.PoseInFrame", "foxglove.PosesInFrame", "foxglove.PointCloud", "foxglove.SceneUpdate",
            "foxglove.FrameTransform"}


def read_mcap(path: Path) -> tuple[dict, list[tuple[str, str, int, bytes]]]:
    """(summary, [(topic, schema name, log_time ns, data)]) through the mcap library's reader."""
    from mcap.reader import make_reader

    with path.open("rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        messages = [(ch.topic, sc.name if sc else "", m.log_time, m.data) for sc, ch, m in reader.iter_messages()]
    return summary, messages


@pytest.fixture(scope="module")
def exported(sim_runs: Runs, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("mcap") / "yard.mcap"
    assert main(["export", str(sim_runs.root), "--mcap", str(out)]) == 0
    return out


def test_schema_names_counts_and_encodings(exported: Path, sim_runs: Runs) -> None:
    summary, messages = read_mcap(exported)
    schemas = {s.name: s.encoding for s in summary.schemas.values()}
    assert set(schemas) >= FOXGLOVE
    assert set(schemas.values()) == {"jsonschema"}
    assert {c.message_encoding for c in summary.channels.values()} == {"json"}
    counts = Counter(topic for topic, *_ in messages)
    slam, control = read_result(sim_runs.slam), read_result(sim_runs.control)
    traj = read_tum(sim_runs.slam / "trajectory.tum")
    with open_log(sim_runs.log) as lg:
        n_gt = len(lg.ground_truth())
    assert counts["/eval/slam/lio/pose"] == len(traj)
    assert counts["/eval/slam/lio/path"] == 1
    assert counts["/eval/slam/lio/ape"] == slam.series["ape_err_m"].size
    if (sim_runs.slam / "trajectory_online.tum").exists():  # written since issue 16
        assert counts["/eval/slam/lio/online/pose"] == len(read_tum(sim_runs.slam / "trajectory_online.tum"))
        assert counts["/eval/slam/lio/online/ape"] == slam.series["ape_online_err_m"].size
    assert counts["/eval/ground_truth/pose"] == n_gt
    assert counts["/eval/slam/lio/map"] == 1
    assert counts["/eval/slam/lio/keyframes"] == len(read_tum(sim_runs.slam / "keyframes.tum"))
    assert counts["/eval/control/recorded/tracking"] == control.series["recorded_t"].size
    assert counts["/eval/control/recorded/planned_path"] == counts["/eval/control/recorded/driven_path"] == 1
    assert counts["/eval/tf"] == 1 + 2 * len(traj)  # the alignment, then lio/map -> base_link and -> odom per pose
    assert summary.statistics.message_count == len(messages)


def test_every_stamp_inside_the_log_and_equal_to_the_body_stamp(exported: Path, sim_runs: Runs) -> None:
    _, messages = read_mcap(exported)
    with open_log(sim_runs.log) as lg:
        start, end = lg.start_s, lg.end_s
    for topic, _schema, t_ns, data in messages:
        assert start - 1e-6 <= t_ns * 1e-9 <= end + 1e-6, topic
        body = json.loads(data)
        if "timestamp" in body:
            assert body["timestamp"]["sec"] * 1_000_000_000 + body["timestamp"]["nsec"] == t_ns, topic


def test_decoded_poses_equal_the_tum_file(exported: Path, sim_runs: Runs) -> None:
    _, messages = read_mcap(exported)
    poses = [(t, json.loads(d)) for topic, _s, t, d in messages if topic == "/eval/slam/lio/pose"]
    traj = read_tum(sim_runs.slam / "trajectory.tum")
    assert len(poses) == len(traj)
    for (t_ns, body), stamp, xyz, q in zip(poses, traj.stamps, traj.positions, traj.quat_xyzw, strict=True):
        p, o = body["pose"]["position"], body["pose"]["orientation"]
        assert body["frame_id"] == "lio/map"  # the estimate's own, namespaced frame
        assert abs(t_ns * 1e-9 - stamp) < 1e-6  # float64 of a 1.7e9 s stamp: 0.24 us resolution
        np.testing.assert_allclose([p["x"], p["y"], p["z"]], xyz, rtol=0, atol=1e-12)
        np.testing.assert_allclose([o["x"], o["y"], o["z"], o["w"]], q, rtol=0, atol=1e-12)


def test_map_cloud_and_control_values_decode_to_the_results(exported: Path, sim_runs: Runs) -> None:
    import base64

    _, messages = read_mcap(exported)
    by_topic: dict[str, list[dict]] = {}
    for topic, _s, _t, data in messages:
        by_topic.setdefault(topic, []).append(json.loads(data))
    cloud = by_topic["/eval/slam/lio/map"][0]
    xyz = np.frombuffer(base64.b64decode(cloud["data"]), dtype="<f4").reshape(-1, cloud["point_stride"] // 4)
    import open3d as o3d

    full = np.asarray(o3d.io.read_point_cloud(str(sim_runs.slam / "map.ply")).points)
    assert 0 < xyz.shape[0] <= 100_000
    assert xyz.shape[0] == min(full.shape[0], xyz.shape[0])
    np.testing.assert_allclose(xyz.min(axis=0), full.min(axis=0), atol=1e-3)
    control = read_result(sim_runs.control)
    tracking = by_topic["/eval/control/recorded/tracking"]
    np.testing.assert_allclose([m["v_left_mps"] for m in tracking], control.series["recorded_left_v_meas"])
    np.testing.assert_allclose([m["error_right_mps"] for m in tracking],
                               control.series["recorded_right_v_meas"] - control.series["recorded_right_v_ref"])
    np.testing.assert_allclose([m["funnel_upper_mps"] for m in tracking], control.series["recorded_funnel_o"])


OFFICIAL = Path(__file__).resolve().parents[2] / "mrnc_eval" / "export" / "foxglove_schemas"


def test_every_message_validates_against_the_official_foxglove_schemas(exported: Path, tmp_path: Path) -> None:
    """The embedded schema of every foxglove.* channel is the published file (foxglove-sdk,
    SOURCE.md), and every message validates against it (ours: against the embedded one). The yard
    run need not raise an event (its one finding was a borderline IMU-offset estimate, 23.5 +- 11 ms,
    that a better wheel guess moved under 2 sigma): foxglove.Log comes from an info result with a
    warning, exported the same way."""
    from mrnc_eval.config import Config, config_hash, dump_config
    from mrnc_eval.results import RunResult, write_result
    from tests.needs import need_module
    from tests.reports.conftest import write_imu_log

    jsonschema = need_module("jsonschema", "jsonschema is not installed (pip install 'mrnc-eval[test]')")
    validators: dict[str, object] = {}
    topics: set[str] = set()
    n = _validate_all(exported, validators, topics, jsonschema)
    bag = write_imu_log(tmp_path / "imu.bag", 40, "bag")
    write_result(RunResult(kind="info", log_path=str(bag), log_id="imu", warnings=["a warning"],
                           config_hash=config_hash(Config())), tmp_path / "info", dump_config(Config()))
    assert main(["export", str(tmp_path / "info"), "--mcap", str(tmp_path / "info.mcap")]) == 0
    _validate_all(tmp_path / "info.mcap", validators, topics, jsonschema)
    assert len(topics) >= 10
    assert {"foxglove.SceneUpdate", "foxglove.FrameTransform", "foxglove.PointCloud", "foxglove.Log"} <= set(validators)
    assert n > 1000


def _validate_all(path: Path, validators: dict[str, object], topics: set[str], jsonschema: object) -> int:
    """Validate every message of the export at `path` (schemas checked against the official files on
    first sight, into `validators`; topics into `topics`); returns the message count."""
    from mcap.reader import make_reader

    n = 0
    with path.open("rb") as fh:
        for schema, channel, message in make_reader(fh).iter_messages():
            if schema.name not in validators:
                embedded = json.loads(schema.data)
                if schema.name.startswith("foxglove."):
                    official = json.loads((OFFICIAL / f"{schema.name.removeprefix('foxglove.')}.json").read_text())
                    assert embedded == official, schema.name
                validators[schema.name] = jsonschema.Draft7Validator(embedded)  # type: ignore[attr-defined]
            validators[schema.name].validate(json.loads(message.data))  # type: ignore[attr-defined]
            topics.add(channel.topic)
            n += 1
    return n


def test_the_official_schema_refuses_what_the_hand_copy_let_through() -> None:
    """Negative control: a SceneEntity without the empty primitive lists (the old hand copy's
    shape) fails the official SceneUpdate schema."""
    from mrnc_eval.export.mcap_file import line_entity
    from mrnc_eval.export.schemas import SCENE_UPDATE
    from tests.needs import need_module

    jsonschema = need_module("jsonschema", "jsonschema is not installed (pip install 'mrnc-eval[test]')")
    entity = line_entity(0, "lio/map", "g", [])
    jsonschema.validate({"deletions": [], "entities": [entity]}, SCENE_UPDATE)
    old = {k: v for k, v in entity.items() if k not in ("arrows", "cubes", "texts")}
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({"deletions": [], "entities": [old]}, SCENE_UPDATE)


def test_with_log_copies_every_topic_raw(sim_runs: Runs, tmp_path: Path) -> None:
    from mcap.reader import make_reader

    out = tmp_path / "all.mcap"
    assert main(["export", str(sim_runs.slam), "--mcap", str(out), "--with-log"]) == 0
    with sim_runs.log.open("rb") as fh:
        original = Counter(ch.topic for _s, ch, _m in make_reader(fh).iter_messages())
        fh.seek(0)
        first = {}
        for _s, ch, m in make_reader(fh).iter_messages():
            first.setdefault(ch.topic, m.data)
    summary, messages = read_mcap(out)
    counts = Counter(topic for topic, *_ in messages)
    for topic, n in original.items():
        assert counts[topic] == n, topic
        assert next(d for t, _s, _ts, d in messages if t == topic) == first[topic]
    assert {s.encoding for s in summary.schemas.values()} >= {"jsonschema", "ros2msg"}


def test_with_log_from_a_ros1_bag_keeps_ros1_encoding(tmp_path: Path) -> None:
    from mrnc_eval.config import Config, config_hash, dump_config
    from mrnc_eval.results import RunResult, write_result
    from tests.reports.conftest import write_imu_log

    bag = write_imu_log(tmp_path / "imu.bag", 40, "bag")
    write_result(RunResult(kind="info", log_path=str(bag), log_id="imu", warnings=["IMU <only> & short"],
                           config_hash=config_hash(Config())), tmp_path / "info", dump_config(Config()))
    out = tmp_path / "imu_export.mcap"
    assert main(["export", str(tmp_path / "info"), "--mcap", str(out), "--with-log"]) == 0
    summary, messages = read_mcap(out)
    imu = [c for c in summary.channels.values() if c.topic == "/imu"]
    assert imu
    assert imu[0].message_encoding == "ros1"
    assert summary.schemas[imu[0].schema_id].encoding == "ros1msg"
    assert sum(t == "/imu" for t, *_ in messages) == 40
    log = [json.loads(d) for t, _s, _ts, d in messages if t == "/eval/events"]
    assert log[0]["message"] == "[warning] IMU <only> & short"


def test_never_overwrites_without_force_and_leaves_nothing_on_failure(sim_runs: Runs, tmp_path: Path,
                                                                      capsys) -> None:
    out = tmp_path / "x.mcap"
    out.write_bytes(b"keep me")
    assert main(["export", str(sim_runs.slam), "--mcap", str(out)]) == 4  # the one overwrite rule: exit 4
    assert out.read_bytes() == b"keep me"
    assert "--force" in capsys.readouterr().err
    assert main(["export", str(sim_runs.slam), "--mcap", str(out), "--force"]) == 4  # not a file we wrote
    assert out.read_bytes() == b"keep me"
    assert "not a file this tool wrote" in capsys.readouterr().err
    broken = tmp_path / "broken"
    broken.mkdir()
    for name in ("result.json", "config.yaml", "series.npz"):
        (broken / name).write_bytes((sim_runs.slam / name).read_bytes())  # no trajectory.tum
    assert main(["export", str(broken), "--mcap", str(tmp_path / "new.mcap")]) == 4
    assert "trajectory.tum" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken", "x.mcap"]  # no partial or temporary file
    out.unlink()
    assert main(["export", str(sim_runs.slam), "--mcap", str(out)]) == 0
    assert main(["export", str(sim_runs.slam), "--mcap", str(out), "--force"]) == 0  # our own export: replaced
    assert out.read_bytes()[:8] == b"\x89MCAP0\r\n"
    assert out.stat().st_mode & 0o044 == 0o044 or os.umask(os.umask(0)) & 0o044  # readable as any file is


def test_downsample_keeps_extent_and_caps_the_size() -> None:
    from mrnc_eval.export.topics import downsample

    rng = np.random.default_rng(0)
    xyz = rng.uniform(-50, 50, size=(300_000, 3))
    small = downsample(xyz, 100_000)
    assert 10_000 < small.shape[0] <= 100_000
    assert np.isin(small.view([("", small.dtype)] * 3), xyz.view([("", xyz.dtype)] * 3)).all()
    np.testing.assert_allclose(small.min(axis=0), xyz.min(axis=0), atol=2.0)
    np.testing.assert_allclose(small.max(axis=0), xyz.max(axis=0), atol=2.0)
    assert downsample(xyz[:50], 100).shape[0] == 50


def test_online_trajectory_is_exported_when_the_result_has_one(sim_runs: Runs, tmp_path: Path) -> None:
    import shutil

    run = tmp_path / "slam"
    shutil.copytree(sim_runs.slam, run)
    lines = (run / "trajectory.tum").read_text(encoding="utf-8").splitlines()
    (run / "trajectory_online.tum").write_text("\n".join(lines[::2]) + "\n", encoding="utf-8")
    out = tmp_path / "online.mcap"
    assert main(["export", str(run), "--mcap", str(out)]) == 0
    _, messages = read_mcap(out)
    online = [json.loads(d) for t, _s, _ts, d in messages if t == "/eval/slam/lio/online/pose"]
    assert len(online) == len(lines[::2])
    assert online[1]["pose"]["position"]["x"] == pytest.approx(float(lines[2].split()[1]), abs=1e-12)


def test_with_log_from_a_ros2_sqlite_bag_keeps_cdr(tmp_path: Path) -> None:
    from mrnc_eval.config import Config, config_hash, dump_config
    from mrnc_eval.results import RunResult, write_result
    from tests.reports.conftest import write_imu_log

    bag = write_imu_log(tmp_path / "imu_db3", 25, "db3")
    write_result(RunResult(kind="info", log_path=str(bag), log_id="imu", config_hash=config_hash(Config())),
                 tmp_path / "info", dump_config(Config()))
    out = tmp_path / "db3_export.mcap"
    assert main(["export", str(tmp_path / "info"), "--mcap", str(out), "--with-log"]) == 0
    summary, messages = read_mcap(out)
    (imu,) = [c for c in summary.channels.values() if c.topic == "/imu"]
    schema = summary.schemas[imu.schema_id]
    assert (imu.message_encoding, schema.encoding, schema.name) == ("cdr", "ros2msg", "sensor_msgs/msg/Imu")
    assert b"geometry_msgs/Vector3 angular_velocity" in schema.data
    assert sum(t == "/imu" for t, *_ in messages) == 25
