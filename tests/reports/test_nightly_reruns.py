"""Nightly reruns are keyed on (log, configuration hash): a changed gate, parameter or log is
processed again, an unchanged one is not (on any night), --force re-runs all; the summary says
"N new, M unchanged, K re-run". An unreachable --scheduler is one line within seconds."""

from __future__ import annotations

import os
import socket
import time
from pathlib import Path

import pytest

from mrnc_eval.cli import main

from .conftest import write_imu_log
from .nightly_workers import CALLS_ENV

INFO = "tests.reports.nightly_workers:info_analysis"


def _night(logs: Path, out: Path, night: str, *sets: str, force: bool = False,
           monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> tuple[str, int]:
    """(summary line, analyses run): nightly.main as the CLI calls it, with the fast info analysis."""
    from mrnc_eval.commands import nightly
    from mrnc_eval.config import load_config

    calls = out.parent / f"calls-{night}-{time.monotonic_ns()}"
    calls.mkdir()
    monkeypatch.setenv(CALLS_ENV, str(calls))
    nightly.main(logs, load_config(None, sets), out=out, jobs=1, scheduler=None, since=None, gates=None,
                 date=night, pdf=False, analysis=INFO, force=force)
    line = [x for x in capsys.readouterr().out.splitlines() if x.startswith("night ")][-1]
    return line, len(list(calls.iterdir()))


def test_reruns_follow_the_log_and_the_configuration(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    write_imu_log(logs / "a.mcap", 40)
    write_imu_log(logs / "b.mcap", 60)
    out = tmp_path / "out"
    gate = "gates.ape_rmse_max_m=0.2"

    def run(night: str, *sets: str, force: bool = False) -> tuple[str, int]:
        return _night(logs, out, night, *sets, force=force, monkeypatch=monkeypatch, capsys=capsys)

    line, calls = run("2026-11-01")
    assert calls == 2
    assert "2 new, 0 unchanged, 0 re-run" in line
    assert (out / "latest").resolve() == (out / "2026-11-01").resolve()
    # the same night again, and a new night: nothing changed, nothing is processed
    line, calls = run("2026-11-01")
    assert calls == 0
    assert "0 new, 2 unchanged, 0 re-run" in line
    line, calls = run("2026-11-02")
    assert calls == 0
    assert "0 new, 2 unchanged, 0 re-run" in line
    # a changed parameter (here a gate) re-runs every log
    line, calls = run("2026-11-02", gate)
    assert calls == 2
    assert "0 new, 0 unchanged, 2 re-run" in line
    # a rewritten log is processed again, alone
    write_imu_log(logs / "b.mcap", 70)
    os.utime(logs / "b.mcap", ns=(time.time_ns() + 10**9, time.time_ns() + 10**9))
    line, calls = run("2026-11-02", gate)
    assert calls == 1
    assert "0 new, 1 unchanged, 1 re-run" in line
    # --force re-runs all
    line, calls = run("2026-11-02", gate, force=True)
    assert calls == 2
    assert "0 new, 0 unchanged, 2 re-run" in line


def test_an_unreachable_scheduler_is_one_line_within_seconds(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("distributed", reason="the dask extra is not installed")
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    (tmp_path / "logs").mkdir()
    write_imu_log(tmp_path / "logs" / "a.mcap", 20)  # a folder without logs is refused before
    start = time.monotonic()
    rc = main(["nightly", str(tmp_path / "logs"), "--out", str(tmp_path / "out"), "--no-pdf",
               "--scheduler", f"127.0.0.1:{port}", "--set", "nightly.scheduler_timeout_s=2"])
    took = time.monotonic() - start
    err = capsys.readouterr().err
    assert rc == 2
    assert f"127.0.0.1:{port}" in err
    assert err.count("\n") == 1
    assert took < 10
