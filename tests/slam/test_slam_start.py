"""What a `slam` run does before its first sweep (the cold start, issue 30): a plain command line
skips typer's per-run validators (no pydantic imported; a global option sends it through typer,
which does: the negative control), and gtsam's libraries are handed to the kernel to read ahead
before numpy is even imported, so that a cold page cache reads them while the config and the
log's overview are read."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from mrnc_eval.extras import read_ahead

REPO = Path(__file__).resolve().parents[2]
LOG = REPO / "sample_logs" / "circle_soft_ground.mcap"

SCRIPT = textwrap.dedent("""
    import json, sys
    import mrnc_eval.extras as extras
    calls = []
    real = extras.read_ahead
    def spy(extra):
        calls.append([extra, "numpy" in sys.modules])
        return real(extra)
    extras.read_ahead = spy
    from mrnc_eval.cli import main
    code = main(sys.argv[1:])
    print(json.dumps({"code": code, "pydantic": "pydantic" in sys.modules, "read_ahead": calls,
                      "unneeded": sorted(m for m in ("rosbags", "mcap.reader", "html", "yaml") if m in sys.modules)}))
""")


def _run(tmp_path: Path, *argv: str) -> dict:
    env = {"PYTHONPATH": str(REPO), "HOME": str(tmp_path), "PATH": "/usr/bin:/bin"}
    proc = subprocess.run([sys.executable, "-c", SCRIPT, *argv], cwd=tmp_path, capture_output=True, text=True,
                          timeout=600, env=env, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_a_plain_slam_line_skips_typers_validators_and_reads_gtsam_ahead(tmp_path: Path) -> None:
    args = ["slam", str(LOG), "--n-scans", "2", "--out", str(tmp_path / "out")]
    plain = _run(tmp_path, *args)
    assert plain["code"] == 0
    assert plain["pydantic"] is False
    assert plain["read_ahead"] == [["slam", False]]  # once, before numpy (the config) is imported
    assert plain["unneeded"] == []  # rosbags, mcap.reader (io/ros2_mcap.py), html (reports/tables.py), yaml (config.py)
    through_typer = _run(tmp_path, "-q", *args)  # a global option: typer parses the line
    assert through_typer["code"] == 0
    assert through_typer["pydantic"] is True


def test_read_ahead_advises_gtsams_libraries(monkeypatch: pytest.MonkeyPatch) -> None:
    import importlib.util

    if not hasattr(os, "posix_fadvise"):
        pytest.skip("no posix_fadvise on this platform")
    advised: list[str] = []

    def advise(fd: int, offset: int, length: int, advice: int) -> None:
        assert (offset, length, advice) == (0, 0, os.POSIX_FADV_WILLNEED)  # the whole file, read ahead
        advised.append(os.readlink(f"/proc/self/fd/{fd}"))

    monkeypatch.setattr(os, "posix_fadvise", advise)
    assert read_ahead("slam") == len(advised) > 0
    spec = importlib.util.find_spec("gtsam")
    assert spec is not None
    assert spec.submodule_search_locations
    gtsam_dir = Path(next(iter(spec.submodule_search_locations))).resolve()
    names = [Path(p) for p in advised]
    assert any(p.parent == gtsam_dir and ".so" in p.name for p in names)  # its extension module
    assert all(".so" in p.name for p in names)  # libraries only: no sources, no data


GC_SCRIPT = textwrap.dedent("""
    import gc, json, sys
    import mrnc_eval.gc_pause as gc_pause
    if sys.argv[1] == "never-paused":  # the negative control: collection stays on throughout
        gc_pause.pause = lambda: None
    older = []
    gc.callbacks.append(lambda phase, info: older.append(info["generation"])
                        if phase == "start" and info["generation"] > 0 else None)
    from mrnc_eval.cli import main
    code = main(sys.argv[2:])
    print(json.dumps({"code": code, "older_passes": len(older), "enabled": gc.isenabled(),
                      "frozen": gc.get_freeze_count()}))
""")


def _gc_run(tmp_path: Path, mode: str, *argv: str) -> dict:
    env = {"PYTHONPATH": str(REPO), "HOME": str(tmp_path), "PATH": "/usr/bin:/bin"}
    proc = subprocess.run([sys.executable, "-c", GC_SCRIPT, mode, *argv], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600, env=env, check=False)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_the_collector_is_paused_until_the_slam_loop_and_always_resumed(tmp_path: Path) -> None:
    args = ["slam", str(LOG), "--n-scans", "2", "--out", str(tmp_path / "out")]
    paused = _gc_run(tmp_path, "paused", *args)
    never = _gc_run(tmp_path, "never-paused", *args)
    assert paused["code"] == never["code"] == 0
    assert paused["enabled"]
    assert never["enabled"]
    assert paused["frozen"] == never["frozen"] == 0  # handed back to the collector when the command ends
    assert 3 * paused["older_passes"] <= never["older_passes"]  # generation 1 and 2 passes over them
    failed = _gc_run(tmp_path, "paused", "slam", str(tmp_path / "missing.mcap"), "--out", str(tmp_path / "out"))
    assert failed["code"] != 0
    assert failed["enabled"]


LEAK_SCRIPT = textwrap.dedent("""
    import gc, json, sys, weakref
    from mrnc_eval import gc_pause
    from mrnc_eval.cli import main
    class Node:
        pass
    alive, frozen = [], []
    for argv in (sys.argv[1:], sys.argv[1:2] + ["missing.mcap"] + sys.argv[3:]):  # a good run, a failing one
        node = Node()
        node.me = node  # cyclic garbage left before the command, as a process running many makes
        alive.append(weakref.ref(node))
        del node
        real = gc_pause.resume
        def spy():
            real()
            frozen.append(gc.get_freeze_count())
        gc_pause.resume = spy
        main(argv)
        gc_pause.resume = real
    gc.collect()
    print(json.dumps({"alive": sum(r() is not None for r in alive), "frozen": gc.get_freeze_count(),
                      "frozen_in_run": max(frozen), "enabled": gc.isenabled()}))
""")


def test_a_process_running_many_commands_keeps_no_frozen_garbage(tmp_path: Path) -> None:
    """The start-up's objects are frozen during the SLAM loop and handed back when the command
    ends, so the cyclic garbage that existed at its start is still freed (after a failing command too)."""
    env = {"PYTHONPATH": str(REPO), "HOME": str(tmp_path), "PATH": "/usr/bin:/bin"}
    argv = ["slam", str(LOG), "--n-scans", "2", "--out", str(tmp_path / "out")]
    proc = subprocess.run([sys.executable, "-c", LEAK_SCRIPT, *argv], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600, env=env, check=False)
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["frozen_in_run"] > 20_000  # the pause and freeze still happen
    assert out["enabled"]
    assert out["frozen"] == 0
    assert out["alive"] == 0


def test_gc_pause_only_resumes_what_it_paused() -> None:
    import gc

    from mrnc_eval import gc_pause

    gc.disable()
    try:
        gc_pause.pause()
        gc_pause.resume()
        assert not gc.isenabled()  # the caller's choice kept
    finally:
        gc.enable()
    gc_pause.pause()
    assert not gc.isenabled()
    gc_pause.resume()
    gc_pause.resume()
    assert gc.isenabled()
    gc.unfreeze()


MAIN_SCRIPT = textwrap.dedent("""
    import gc, json, runpy, sys
    sys.argv = ["mrnc_eval", *sys.argv[1:]]
    code = None
    try:
        runpy.run_module("mrnc_eval", run_name="__main__")
    except SystemExit as exc:
        code = exc.code
    print(json.dumps({"code": code, "enabled": gc.isenabled()}))
""")


@pytest.mark.parametrize("verb", [["config"], ["slam", "--dump-config"]])
def test_python_m_resumes_collection_for_other_commands(tmp_path: Path, verb: list[str]) -> None:
    """`python -m mrnc_eval` pauses collection before the CLI's imports: another verb resumes it at
    dispatch, a `slam` line when it ends (here --dump-config, before any log is read)."""
    env = {"PYTHONPATH": str(REPO), "HOME": str(tmp_path), "PATH": "/usr/bin:/bin"}
    proc = subprocess.run([sys.executable, "-c", MAIN_SCRIPT, *verb], cwd=tmp_path, capture_output=True, text=True,
                          timeout=600, env=env, check=False)
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["code"] in (0, None), proc.stderr[-2000:]
    assert out["enabled"]


def test_importing_main_leaves_collection_on() -> None:
    """Only running `python -m mrnc_eval` pauses collection; a tool importing every module must
    not be left with it off (nothing would resume it)."""
    code = "import gc, mrnc_eval.__main__; print(gc.isenabled())"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True,
                          env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})
    assert proc.stdout.strip() == "True"
