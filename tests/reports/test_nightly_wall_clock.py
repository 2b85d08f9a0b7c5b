"""A wall-clock metric (the SLAM's real-time factor) slows down when several logs share the cores
or the SLAM maps more sweeps: a --jobs 2 night, or a night mapping every sweep, is compared only
with nights that ran as many logs at once at the same mapping rate, never flagged as a regression
against a --jobs 1 night at LIO-SAM's rate."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from mrnc_eval.commands import nightly
from mrnc_eval.config import Config

from .nightly_workers import RATE_ENV, RTF_ENV

RTF = "tests.reports.nightly_workers:rtf_analysis"


def night(logs: Path, out: Path, date: str, jobs: int, rtf: float, monkeypatch: pytest.MonkeyPatch,
          rate_hz: float = 5.0) -> list[str]:
    """Run one night (every log re-run) and return the logs flagged for an RTF regression."""
    monkeypatch.setenv(RTF_ENV, str(rtf))
    monkeypatch.setenv(RATE_ENV, str(rate_hz))
    nightly.main(logs, Config(), out=out, jobs=jobs, scheduler=None, since=None, gates=None, date=date, pdf=False,
                 analysis=RTF, force=True)
    return sorted(r.log_id for r in nightly._write_trends(nightly.History(out / "history.sqlite"), out)
                  if r.metric == "slam/rtf")


def test_rtf_of_a_parallel_night_is_not_a_regression_against_a_serial_one(
        imu_logs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "out"
    assert night(imu_logs, out, "2026-11-01", jobs=1, rtf=2.0, monkeypatch=monkeypatch) == []
    # half the real-time factor with two logs sharing two cores: contention, not a regression
    assert night(imu_logs, out, "2026-11-02", jobs=2, rtf=1.0, monkeypatch=monkeypatch) == []
    with sqlite3.connect(out / "history.sqlite") as con:
        stored = dict(con.execute("SELECT night, MIN(value) FROM metrics WHERE metric = ? GROUP BY night",
                                  (nightly.CONCURRENCY_METRIC,)))
    assert stored == {"2026-11-01": 1.0, "2026-11-02": 2.0}
    # negative control: the same drop on a serial night is flagged for every log
    flagged = night(imu_logs, out, "2026-11-03", jobs=1, rtf=1.0, monkeypatch=monkeypatch)
    assert len(flagged) == 5


def test_rtf_of_a_night_mapping_every_sweep_is_not_a_regression_and_its_rate_is_charted(
        imu_logs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "out"
    assert night(imu_logs, out, "2026-11-01", jobs=1, rtf=2.0, monkeypatch=monkeypatch, rate_hz=5.0) == []
    # half the real-time factor for twice the work (slam.mapping_interval_s=0 on 10 Hz logs)
    assert night(imu_logs, out, "2026-11-02", jobs=1, rtf=1.0, monkeypatch=monkeypatch, rate_hz=10.0) == []
    assert "slam/mapping_rate_hz" in (out / "trends.html").read_text()
    # negative control: the same drop at the same rate is flagged for every log
    flagged = night(imu_logs, out, "2026-11-03", jobs=1, rtf=0.5, monkeypatch=monkeypatch, rate_hz=10.0)
    assert len(flagged) == 5
