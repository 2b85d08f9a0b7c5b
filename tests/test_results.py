"""Result directories: round trip, atomic replacement, hostile names."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.errors import InputError
from mrnc_eval.results import Event, Metric, RunResult, Table, read_result, safe_name, write_result


def _result() -> RunResult:
    return RunResult(
        kind="slam", log_path="/logs/a.mcap", log_id="a",
        metrics=[Metric(name="ape_rmse_m", value=0.05, unit="m"),
                 Metric(name="rtf", value=math.inf, unit="", lower_is_better=False)],
        tables=[Table("APE", ["seq1"], ["lio", "kiss"], [[0.1, "Failed"]], unit="m")],
        events=[Event(t_s=1.5, kind="loop_closure", message="kf 10 -> 2", data={"fitness": 0.1})],
        series={"t": np.arange(5.0), "err": np.ones((5, 3), np.float32)},
    )


def test_round_trip(tmp_path: Path) -> None:
    run = write_result(_result(), tmp_path / "run1", "robot: {}\n")
    back = read_result(run)
    assert back.metric("ape_rmse_m").value == 0.05
    assert back.metric("rtf").value == math.inf
    assert back.tables[0].cells == [[0.1, "Failed"]]
    assert back.events[0].data == {"fitness": 0.1}
    np.testing.assert_array_equal(back.series["err"], np.ones((5, 3), np.float32))
    assert (run / "config.yaml").read_text() == "robot: {}\n"


def test_failed_write_keeps_previous_result(tmp_path: Path) -> None:
    run = write_result(_result(), tmp_path / "run1", "a: 1\n")
    bad = _result()
    bad.series = {"x": object()}  # not storable without pickle
    with pytest.raises(TypeError, match="dtype object"):  # write_result refuses series that would need pickle
        write_result(bad, run, "a: 2\n")
    assert read_result(run).metric("ape_rmse_m").value == 0.05
    assert [p.name for p in tmp_path.iterdir()] == ["run1"]


def test_missing_result_is_a_clear_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="not a result directory"):
        read_result(tmp_path)


@pytest.mark.parametrize("hostile", ["../../etc/passwd", "/ouster/points", "<script>", "..", ""])
def test_safe_name_cannot_escape(hostile: str) -> None:
    name = safe_name(hostile)
    assert "/" not in name
    assert ".." not in name
    assert "<" not in name
    assert name
