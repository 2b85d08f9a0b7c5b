"""Issue 30: the lio run on two cores. What needs no pose (range image, feature labels, the ground
test's pixel pairs: slam/sweep_prep.py) is prepared in the reader thread ahead of the mapping loop;
everything that reads the replay's state (deskew by graph #2's prediction, matching, graphs) stays
in the loop's order. So `--threads 1` (all in turn on one thread, OpenMP held to it) and the
default give the same trajectory to the byte; and a pipeline that ran the state-dependent part
ahead too (deskew of a sweep with the prediction from before the previous sweep's match) does
not: the comparison sees an ordering mistake. The IMU-LiDAR offset re-matched after the run on
two threads is the serial one too."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mrnc_eval.cli import main
from mrnc_eval.commands.slam import SweepWindow, run_log
from mrnc_eval.config import Config, replace_path
from mrnc_eval.io import open_log
from mrnc_eval.slam import replay
from mrnc_eval.slam.features import _ground_of, ground_mask, vertical_neighbours
from mrnc_eval.slam.range_image import project
from mrnc_eval.slam.sweep_prep import prepare_sweep

SAMPLE = Path(__file__).resolve().parents[2] / "sample_logs" / "loop_forest.bag"
WINDOW = SweepWindow(start_s=33.0, n_scans=30)  # 4 s of the 10 Hz part: keyframes, graph #2 predicting


def _run(tmp_path: Path, name: str, threads: int) -> tuple[bytes, float | None]:
    """(trajectory.tum's bytes, the IMU-LiDAR offset found, s)."""
    cfg = replace_path(replace_path(Config(), "slam.mapping_interval_s", 0.0), "slam.threads", threads)
    result = run_log(SAMPLE, cfg, tmp_path / name, method="lio", window=WINDOW)
    offset = next((m.value for m in result.metrics if m.name == "imu_time_offset_s"), None)
    return (tmp_path / name / "trajectory.tum").read_bytes(), offset


def _trajectory(tmp_path: Path, name: str, threads: int) -> bytes:
    return _run(tmp_path, name, threads)[0]


@pytest.fixture(scope="module")
def serial_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[bytes, float | None]:
    return _run(tmp_path_factory.mktemp("serial"), "t1", 1)


@pytest.fixture(scope="module")
def serial(serial_run: tuple[bytes, float | None]) -> bytes:
    return serial_run[0]


def test_two_threads_give_the_serial_poses_and_offset_to_the_byte(serial_run: tuple[bytes, float | None],
                                                                  tmp_path: Path) -> None:
    serial, offset = serial_run
    assert serial.count(b"\n") >= 25
    assert offset is not None  # the re-match ran (two workers after the run)
    assert _run(tmp_path, "t2", 2) == (serial, offset)


def test_a_stale_prediction_for_deskew_changes_the_poses(serial: bytes, tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """Negative control: deskew each sweep with the motion state from before the previous sweep was
    matched (what deskewing one sweep ahead of the loop would use): the trajectory differs."""
    real_record, real_deskew = replay._Replay.record, replay._Replay.deskew
    stale: dict[int, Any] = {}

    def record(self: Any, *args: Any) -> None:
        stale[id(self)] = copy.copy(self.st)  # the state as it was before this sweep's pose
        real_record(self, *args)

    def deskew(self: Any, image: Any, stamp: float) -> np.ndarray:
        fresh = self.st
        self.st = stale.get(id(self), fresh)
        try:
            return np.asarray(real_deskew(self, image, stamp))
        finally:
            self.st = fresh

    monkeypatch.setattr(replay._Replay, "record", record)
    monkeypatch.setattr(replay._Replay, "deskew", deskew)
    assert _trajectory(tmp_path, "stale", 2) != serial


def test_prepared_sweeps_depend_on_the_sweep_alone_and_the_ground_kernel_matches() -> None:
    """The prepared arrays are the same in any thread, for any state; the ground test at the edge
    candidates (C, from the prepared pixel pairs) gives ground_mask's (numpy) answers there."""
    cfg = Config().slam
    with open_log(SAMPLE) as lg:
        sweeps = [s for _, s in zip(range(3), lg.sweeps(), strict=False)]
    for sweep in sweeps:
        a, b = prepare_sweep(sweep, cfg), prepare_sweep(sweep, cfg)
        assert a.labels is not None
        assert a.vertical is not None
        assert b.labels is not None
        assert np.array_equal(a.labels, b.labels)
        assert np.array_equal(a.vertical, b.vertical)
        image = project(sweep, cfg.sensor, cfg.features)
        assert np.array_equal(image.points, a.image.points)
        np.testing.assert_array_equal(vertical_neighbours(image), a.vertical)
        edges = np.flatnonzero(a.labels == 1)
        assert edges.size > 50
        tan_max = float(np.tan(np.radians(cfg.features.ground_max_angle_deg)))
        expected = ground_mask(image, image.points, cfg.features.ground_max_angle_deg)[edges]
        assert 0 < expected.sum() < edges.size  # both answers occur
        np.testing.assert_array_equal(_ground_of(image.points, edges, a.vertical, tan_max), expected)


def test_threads_option_sets_the_config_key(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["slam", "--dump-config", "--threads", "1"]) == 0
    assert "threads: 1" in capsys.readouterr().out
    assert main(["slam", "--dump-config", "--threads", "-1"]) != 0  # a usage error, not a run
