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
    assert code == 130, err
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


def _swallowed_ctrl_c() -> None:
    """A Ctrl-C whose handler ran inside a generator's close: Python prints "Exception ignored"
    and goes on, as it does for any exception raised in a finaliser."""
    from mrnc_eval.errors import interrupt

    def sweeps():
        try:
            yield 1
        finally:
            interrupt()

    it = sweeps()
    next(it)
    del it  # the generator is closed here; its Interrupted is swallowed


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")  # the swallowed Ctrl-C itself
def test_a_swallowed_ctrl_c_commits_no_result_and_no_output(tmp_path: Path) -> None:
    from mrnc_eval.errors import Interrupted, forget_interrupt
    from mrnc_eval.outputs import write_output
    from mrnc_eval.results import RunResult, write_result

    result = RunResult(kind="slam", log_path=str(LOG), log_id="x")
    write_result(result, tmp_path / "before", "")  # the negative control: no Ctrl-C, committed
    _swallowed_ctrl_c()
    try:
        with pytest.raises(Interrupted):
            write_result(result, tmp_path / "run", "")
        with pytest.raises(Interrupted):
            write_output(tmp_path / "table.csv", "a,b\n")
    finally:
        forget_interrupt()
    assert (tmp_path / "before" / "result.json").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["before"]  # no run folder, no table, no temporaries


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")  # the swallowed Ctrl-C itself
def test_a_swallowed_ctrl_c_still_exits_130(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    from mrnc_eval import cli

    def run_that_swallows(argv: list[str] | None) -> int:
        _swallowed_ctrl_c()
        return 0

    monkeypatch.setattr(cli, "_run", run_that_swallows)
    assert cli.main(["config"]) == 130
    assert capsys.readouterr().err.strip().splitlines()[-1] == "mrnc-eval: interrupted"
    monkeypatch.setattr(cli, "_run", lambda argv: 0)
    assert cli.main(["config"]) == 0  # the next command starts afresh
