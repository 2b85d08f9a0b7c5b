"""cli_fast: plain `ape`/`rpe`/`slam` command lines skip typer and must call the command exactly as typer
would (same keyword arguments, defaults included); anything else must go to typer."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Annotated, Any

import pytest
import typer

from mrnc_eval import cli
from mrnc_eval.cli_fast import fast_command
from mrnc_eval.commands import slam as slam_command
from mrnc_eval.commands import trajectory_eval

COMMANDS = {"ape": cli.ape, "rpe": cli.rpe, "slam": cli.slam}

PLAIN = [
    ["ape", "ref.tum", "est.tum"],
    ["ape", "ref.tum", "a.tum", "b.tum", "--json"],
    ["ape", "--align", "sim3", "ref.tum", "est.tum", "--relation", "angle_deg", "--max-diff=0.02"],
    ["ape", "ref.tum", "est.tum", "--align", "none", "--relation", "point", "--plane", "xy", "--n-to-align", "50",
     "--offset", "0.25", "--strict", "--sync", "interpolate", "--max-gap", "1e-1", "--decompose",
     "--table", "out.md", "--plot", "p.svg"],
    ["rpe", "ref.tum", "est.tum"],
    ["ape", "ref.tum", "a.tum", "b.tum", "--label", "first", "--label", "second"],  # a repeatable option
    ["rpe", "ref.tum", "est.tum", "--delta", "10", "--delta-unit", "m", "--all-pairs", "--relation", "rot",
     "--pairs-from-reference", "--drift", "--align", "se3", "--json", "--offset", "auto"],
    ["slam", "a.mcap", "--end", "0.25", "--out", "res"],
    ["slam", "a.mcap", "b.bag", "--method", "lio", "--no-loop", "--no-gps", "-t", "/points", "--start", "1",
     "--n-scans", "20", "--threads", "0", "--json", "--set", "slam.mapping_interval_s=0",
     "--set", "slam.loop.enabled=false"],
    ["slam", "a.mcap", "--threads", "2"],
]

TYPER_ONLY = [
    [],
    ["info", "x.bag"],
    ["ape", "--help"],
    ["ape", "ref.tum"],  # EST missing: typer's error
    ["ape", "ref.tum", "est.tum", "--align", "SE3"],  # not a choice as spelled
    ["ape", "ref.tum", "est.tum", "--max-diff", "-1"],  # a value starting with '-'
    ["ape", "ref.tum", "est.tum", "--max-diff", "0x10"],
    ["ape", "ref.tum", "est.tum", "--json", "true"],  # cli_help's flag-value mistake
    ["ape", "ref.tum", "est.tum", "--json=1"],
    ["ape", "ref.tum", "est.tum", "--align", "se3", "--align", "sim3"],  # repeated
    ["ape", "ref.tum", "est.tum", "--", "-odd.tum"],
    ["ape", "ref.tum", "est.tum", "-v"],  # global options: typer hoists them
    ["ape", "ref.tum", "est.tum", "--no-such-option"],
    ["rpe", "ref.tum", "est.tum", "--delta"],  # value missing
    ["ape", "ref.tum", "est.tum", "--json-out"],  # the parameter name is not the flag
    ["ape", "ref.tum", "est.tum", "--align=", "se3"],
    ["slam"],  # LOG missing: typer passes None, the command says why
    ["slam", "--dump-config"],
    ["slam", "a.mcap", "--threads", "-1"],  # below its min=0: typer's range error
    ["slam", "a.mcap", "--threads", "1.5"],
]


def _calls(monkeypatch: pytest.MonkeyPatch, argv: list[str], *, fast: bool) -> list[tuple[str, tuple, dict]]:
    calls: list[tuple[str, tuple, dict]] = []

    def record(name: str):
        def fake(*args: Any, **kwargs: Any) -> None:
            calls.append((name, args, kwargs))
        return fake

    monkeypatch.setattr(trajectory_eval, "ape_main", record("ape"))
    monkeypatch.setattr(trajectory_eval, "rpe_main", record("rpe"))
    monkeypatch.setattr(slam_command, "main", record("slam"))
    if not fast:
        monkeypatch.setattr(cli, "fast_command", lambda *a, **k: None)
    assert cli.main(argv) == 0
    monkeypatch.undo()
    return calls


@pytest.mark.parametrize("argv", PLAIN, ids=" ".join)
def test_plain_lines_call_the_command_as_typer_does(monkeypatch: pytest.MonkeyPatch, argv: list[str]) -> None:
    assert fast_command(argv, COMMANDS) is not None  # else this test would compare typer with itself
    via_typer = _calls(monkeypatch, argv, fast=False)
    via_fast = _calls(monkeypatch, argv, fast=True)
    assert len(via_typer) == 1
    assert via_fast == via_typer
    for a, b in zip(via_fast[0][2].values(), via_typer[0][2].values(), strict=True):
        assert type(a) is type(b)  # an enum stays an enum, a Path a Path


@pytest.mark.parametrize("argv", TYPER_ONLY, ids=lambda a: " ".join(a) or "(empty)")
def test_other_lines_go_to_typer(argv: list[str]) -> None:
    assert fast_command(argv, COMMANDS) is None


def test_a_number_outside_its_declared_range_goes_to_typer() -> None:
    """typer's min=/max= are checked: a value outside them is left to typer, which refuses it."""
    def command(n: Annotated[int, typer.Option(min=1, max=5)] = 3,
                x: Annotated[float, typer.Option(min=0.5)] = 1.0) -> None:
        del n, x

    assert fast_command(["c", "--n", "5", "--x", "0.5"], {"c": command}) == (command, {"n": 5, "x": 0.5})
    for argv in (["c", "--n", "0"], ["c", "--n", "6"], ["c", "--x", "0.25"]):
        assert fast_command(argv, {"c": command}) is None


def test_fast_path_skips_typers_validators(tmp_path: Path) -> None:
    """The reason for the fast path: a plain `ape` imports no pydantic (typer builds its
    per-parameter validators with it); the same line through typer (a global option) does."""
    traj = "\n".join(f"{k} {k} {k % 3} 0 0 0 0 1" for k in range(10)) + "\n"
    (tmp_path / "ref.tum").write_text(traj)
    (tmp_path / "est.tum").write_text(traj)
    code = ("import sys; from mrnc_eval.cli import main; rc = main(sys.argv[1:]); "
            "print(rc, 'pydantic' in sys.modules, file=sys.stderr)")
    args = [str(tmp_path / "ref.tum"), str(tmp_path / "est.tum"), "--json"]
    fast = subprocess.run([sys.executable, "-c", code, "ape", *args], capture_output=True, text=True, check=True)
    slow = subprocess.run([sys.executable, "-c", code, "-q", "ape", *args], capture_output=True, text=True,
                          check=True)
    assert fast.stderr.split()[-2:] == ["0", "False"]
    assert slow.stderr.split()[-2:] == ["0", "True"]
    assert fast.stdout == slow.stdout


def test_fast_path_prints_and_warns_as_typer(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """The whole run, not just the call: the same stdout and the same warning line (the logging
    set-up of the global callback) for a file with a repeated stamp."""
    rows = [f"{k} {k} {k % 3} {k % 5} 0 0 0 1" for k in range(12)]
    (tmp_path / "ref.tum").write_text("\n".join(rows) + "\n")
    (tmp_path / "est.tum").write_text("\n".join([rows[0], *rows]) + "\n")  # stamp 0 twice
    argv = ["ape", str(tmp_path / "ref.tum"), str(tmp_path / "est.tum")]
    assert fast_command(argv, COMMANDS) is not None
    outputs = []
    for fast in (True, False):
        with monkeypatch.context() as m:
            if not fast:
                m.setattr(cli, "fast_command", lambda *a, **k: None)
            assert cli.main(argv) == 0
        outputs.append(capsys.readouterr())
    assert "1 repeated time stamp" in outputs[0].err
    assert outputs[0].out == outputs[1].out
    assert outputs[0].err == outputs[1].err
