"""Exit codes outside the gate/input table: Ctrl-C says "interrupted" and exits 130 without a
half-written night folder; a reader that closes the pipe early (`info LOG | head -1`) is exit 0
with nothing on stderr. Both are in the README's exit-code line."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
LOG = REPO / "sample_logs" / "loop_forest.bag"
ENV = {**os.environ, "PYTHONPATH": str(REPO)}


def _cli(*args: str, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "mrnc_eval", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=ENV, text=True, **kw)


@pytest.mark.parametrize("args", [("info", str(LOG)), ("config",), ("--help",)])
def test_a_closed_pipe_is_exit_0_without_a_traceback(args: tuple[str, ...]) -> None:
    p = _cli(*args)
    assert p.stdout.readline()  # the reader takes one line and goes away, as head -1 does
    p.stdout.close()
    err = p.stderr.read()
    assert p.wait(timeout=120) == 0, err
    assert "Traceback" not in err
    assert "Error" not in err


def _interrupt(p: subprocess.Popen, after_s: float) -> tuple[int, str]:
    time.sleep(after_s)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    return p.returncode, err


def test_ctrl_c_in_slam_says_interrupted_and_keeps_no_run(tmp_path: Path) -> None:
    code, err = _interrupt(_cli("slam", str(LOG), "--out", str(tmp_path / "out")), 4.0)
    assert code == 130
    assert err.strip().splitlines()[-1] == "mrnc-eval: interrupted"
    assert not any((tmp_path / "out").glob("*/result.json"))  # no half-written run folder


def test_ctrl_c_in_nightly_leaves_no_half_written_night(tmp_path: Path) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    shutil.copy(LOG, logs / "forest.bag")
    out = tmp_path / "reports"
    p = _cli("nightly", str(logs), "--out", str(out), "--jobs", "1", "--no-pdf", "--date", "2026-11-20")
    deadline = time.monotonic() + 120.0
    while not (out / ".nightly.lock").exists() and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)  # the night has begun: its lock is held (a fixed delay raced a quiet machine's run)
    code, err = _interrupt(p, 0.5)  # inside the log's job: imports and the SLAM warm-up take longer
    assert code == 130, err
    assert "mrnc-eval: interrupted" in err
    assert "Traceback" not in err
    assert not (out / "2026-11-20").exists()  # the night had finished no log: its folder is gone
    assert not (out / ".nightly.lock").exists()
