"""A recording split into several files, given as one log on the command line
("a.mcap,b.mcap"): `info`, and `log:/topic` references of ape."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mrnc_eval.cli import main
from mrnc_eval.data import Trajectory
from mrnc_eval.errors import InputError
from mrnc_eval.io import open_log
from mrnc_eval.io.trajectory_files import read_trajectory, write_tum
from mrnc_eval.io.writers import LogWriter


def _odometry(t: np.ndarray) -> Trajectory:
    return Trajectory(t, np.c_[t, np.sin(t), 0.1 * t], Rotation.from_euler("z", 0.2 * t[:, None]).as_quat())


def _split(tmp_path: Path, fmt: str, suffix: str) -> tuple[list[Path], Trajectory]:
    t = np.arange(0.0, 20.0, 0.05) + 50.0
    whole = _odometry(t)
    paths = []
    for k, part in enumerate((slice(0, 200), slice(200, None))):
        path = tmp_path / f"run_{k}{suffix}"
        with LogWriter(path, fmt) as w:
            w.write_odometry("/odom", Trajectory(t[part], whole.positions[part], whole.quat_xyzw[part]), "odom",
                             "base_link")
        paths.append(path)
    return paths, whole


@pytest.mark.parametrize(("fmt", "suffix"), [("mcap", ".mcap"), ("bag", ".bag")])
def test_split_log_reads_as_one(tmp_path: Path, fmt: str, suffix: str, capsys: pytest.CaptureFixture[str]) -> None:
    paths, whole = _split(tmp_path, fmt, suffix)
    spec = ",".join(str(p) for p in paths)
    traj = read_trajectory(f"{spec}:/odom")
    np.testing.assert_allclose(traj.stamps, whole.stamps)
    np.testing.assert_allclose(traj.positions, whole.positions, atol=1e-12)
    with open_log(spec) as log:
        assert [p.name for p in log.paths] == [p.name for p in paths]
    assert main(["info", spec, "--json"]) == 0
    info = json.loads(capsys.readouterr().out)["results"][0]
    assert next(t for t in info["topics"] if t["topic"] == "/odom")["count"] == len(whole)
    write_tum(tmp_path / "gt.tum", whole)
    assert main(["ape", str(tmp_path / "gt.tum"), f"{spec}:/odom", "--json", "--align", "none"]) == 0
    out = json.loads(capsys.readouterr().out)["results"][0]["stats"]
    assert out["n"] == len(whole)
    assert out["max"] < 1e-9


def test_split_log_of_mixed_kinds_is_refused(tmp_path: Path) -> None:
    (tmp_path / "m").mkdir()
    (tmp_path / "b").mkdir()
    mcap, _ = _split(tmp_path / "m", "mcap", ".mcap")
    bag, _ = _split(tmp_path / "b", "bag", ".bag")
    with pytest.raises(InputError, match=r"must be of one kind: run_0\.mcap \(ros2-mcap\), run_1\.bag \(ros1\)"):
        open_log(f"{mcap[0]},{bag[1]}")
