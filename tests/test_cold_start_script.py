"""benchmarks/cold_start.py's own housekeeping (its timings need root and kiss-icp: not run here)."""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

from benchmarks import cold_start


def test_the_scans_written_for_kiss_icp_are_removed_after_the_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """The log's clouds as .bin scans (~0.4 GB for forest30) went to a temporary folder that was never
    removed: every run left them in /tmp. Now the folder goes when the run ends. Negative control: the
    folder did exist while the commands were timed, with the scans in it."""
    seen: list[Path] = []

    def scans(log: Path, folder: Path) -> Path:
        folder.mkdir(parents=True)
        for k in range(3):
            np.zeros((4, 4), np.float32).tofile(folder / f"{k:06d}.bin")
        return folder

    def timed(cmd: list[str], cwd: Path) -> tuple[float, float, float]:
        seen.append(cwd)
        assert len(list((cwd / "scans").iterdir())) == 3
        return 1.0, 1.0, 100.0

    monkeypatch.setattr(cold_start, "scans_folder", scans)
    monkeypatch.setattr(cold_start, "timed", timed)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(sys, "argv", ["cold_start", str(tmp_path / "log.mcap"), "--warm", "--rounds", "1"])
    cold_start.main()
    assert len(seen) == 4  # the two pairs, one round
    assert "whole run: lio / kiss_icp_pipeline = 1.00" in capsys.readouterr().out
    assert not list(tmp_path.iterdir())
