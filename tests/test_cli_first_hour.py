"""Issue 19, a newcomer's first hour: help that keeps its placeholders and shows an example,
flags that are flags, global options after the verb, did-you-mean for config keys and roles,
one config subtree, one-line YAML errors."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest
import yaml

from mrnc_eval import cli
from mrnc_eval.cli import main
from mrnc_eval.cli_help import EXAMPLES, hoist_global_options
from mrnc_eval.config import Config, as_dict


def _verbs() -> list[str]:
    import typer

    return sorted(typer.main.get_command(cli.app).commands)  # type: ignore[attr-defined]


VERBS = _verbs()


def test_every_verb_has_an_example() -> None:
    missing = [v for v in VERBS if v not in EXAMPLES]
    assert not missing, f"add an example for {missing} to mrnc_eval/cli_help.py EXAMPLES (and the README's verb table)"


def _help(verb: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> str:
    monkeypatch.setenv("COLUMNS", "240")  # wide enough that no placeholder or example is wrapped
    assert main([verb, "--help"]) == 0
    return capsys.readouterr().out


@pytest.mark.parametrize("verb", VERBS)
def test_every_verb_help_has_plain_metavars_and_an_example(verb: str, capsys: pytest.CaptureFixture[str],
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    if verb not in EXAMPLES:
        pytest.fail(f"no example for {verb} in mrnc_eval/cli_help.py EXAMPLES")
    out = _help(verb, capsys, monkeypatch)
    for python_type in ("<bool>", "<str>", "<int>", "<float>", "<path>", "<list[", "{", "}"):
        assert python_type not in out, f"{verb} --help shows {python_type!r}"
    assert "Example" in out
    for example in EXAMPLES[verb]:
        assert example in out


def test_help_placeholders_survive_the_markup(capsys: pytest.CaptureFixture[str],
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    assert "OUT/<run>/" in _help("slam", capsys, monkeypatch)
    assert "REPORT_ROOT/<date>/index.html" in _help("nightly", capsys, monkeypatch)
    assert "<seq>/<method>.tum" in _help("table", capsys, monkeypatch)
    assert "skid-steer wheeled mobile robot (SSWMR)" in _help("simulate", capsys, monkeypatch)


@pytest.mark.parametrize(("verb", "listed"), [
    ("slam", "[lio | kiss-icp]"), ("ape", "[xy | xz | yz]"),
    ("simulate", "[yard | forest | corridor | field | open_field]"),
    ("simulate", "[circle | figure8 | loop | line]"), ("simulate", "[os0-128 | os0-64 | os0-32]"),
    ("simulate", "[mcap | db3 | bag]"), ("simulate", "[ideal | field]"),
])
def test_choices_are_listed(verb: str, listed: str, capsys: pytest.CaptureFixture[str],
                            monkeypatch: pytest.MonkeyPatch) -> None:
    assert listed in _help(verb, capsys, monkeypatch)


def test_cli_choices_match_what_the_commands_accept() -> None:
    from mrnc_eval.commands.slam import METHODS
    from mrnc_eval.recording.recorder import LIDAR_MODELS, PATHS
    from mrnc_eval.sim.scene import SCENES

    assert tuple(cli.SlamMethod) == METHODS
    assert tuple(cli.Scene) == SCENES
    assert tuple(cli.SimPath) == PATHS
    assert tuple(cli.LidarModel) == tuple(LIDAR_MODELS)


def test_examples_use_existing_verbs_and_options() -> None:
    import typer

    group = typer.main.get_command(cli.app)
    for verb, examples in EXAMPLES.items():
        command = group.commands[verb]  # type: ignore[attr-defined]
        known = {o for p in command.params for o in (*p.opts, *p.secondary_opts)}
        for example in examples:
            words = shlex.split(example.split(">")[0])
            assert words[:2] == ["mrnc-eval", verb]
            unknown = [w for w in words if w.startswith("--") and w not in known]
            assert not unknown, f"{example!r}: {unknown}"


def test_a_flag_refuses_a_truth_word_instead_of_taking_it_as_a_log(capsys: pytest.CaptureFixture[str],
                                                                   tmp_path: Path) -> None:
    assert main(["slam", "--no-loop", "true", str(tmp_path / "x.bag")]) == 2
    err = capsys.readouterr().err
    assert "--no-loop is a flag" in err


def test_global_options_are_accepted_after_the_verb(capsys: pytest.CaptureFixture[str]) -> None:
    assert hoist_global_options(["slam", "a.bag", "--debug", "-vv"]) == ["--debug", "-vv", "slam", "a.bag"]
    assert hoist_global_options(["ape", "--", "-v"]) == ["ape", "--", "-v"]
    cli._state["debug"] = False
    assert main(["config", "robot.mass_kg", "--debug"]) == 0
    assert cli._state["debug"] is True
    cli._state["debug"] = False


def test_mistyped_config_key_gets_a_did_you_mean(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "--set", "control.raid.bta=1.5"]) == 2
    assert "did you mean control.raid.beta?" in capsys.readouterr().err


def test_unknown_role_is_rejected_with_a_did_you_mean(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "--set", "io.roles.lidr=/ouster/points"]) == 2
    err = capsys.readouterr().err
    assert "io.roles.lidr: unknown role" in err
    assert "did you mean lidar?" in err


def test_config_prints_one_subtree_that_loads_back(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "slam.loop"]) == 0
    text = capsys.readouterr().out
    assert yaml.safe_load(text) == {"slam": {"loop": as_dict(Config())["slam"]["loop"]}}
    assert main(["config", "slam.lop"]) == 2
    assert "did you mean slam.loop?" in capsys.readouterr().err


def test_yaml_errors_are_one_line_without_literal_newlines(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("a: [1\nb: 2\n", encoding="utf-8")
    assert main(["config", "-c", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "invalid YAML" in err
    assert "\\n" not in err
    assert err.count("\n") == 1


@pytest.mark.parametrize("columns", ["70", "80", "100"])
@pytest.mark.parametrize("verb", ["simulate", "ape", "rpe", "slam", "control"])
def test_choices_never_break_inside_a_word_on_a_narrow_terminal(verb: str, columns: str,
                                                                 capsys: pytest.CaptureFixture[str],
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    import re

    import typer

    monkeypatch.setenv("COLUMNS", columns)
    assert main([verb, "--help"]) == 0
    out = capsys.readouterr().out
    words = set(re.findall(r"[\w.-]+", out))
    command = typer.main.get_command(cli.app).commands[verb]  # type: ignore[attr-defined]
    import enum
    import typing

    checked = 0
    for param in command.params:
        annotation = getattr(getattr(param, "type_descriptor", None), "annotation", None)
        enums = [a for a in (annotation, *typing.get_args(annotation))
                 if isinstance(a, type) and issubclass(a, enum.Enum)]
        for choice in (c.value for e in enums for c in e):
            checked += 1
            assert str(choice) in words, f"{verb} --help splits the choice {choice!r} at {columns} columns"
    assert checked >= 2  # the check saw the verb's choices


def test_help_says_where_ground_truth_comes_from(capsys: pytest.CaptureFixture[str],
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    for verb in ("slam", "nightly"):
        out = " ".join(_help(verb, capsys, monkeypatch).split())
        assert "io.roles.ground_truth=TOPIC" in out
        assert "<log>.gt.tum beside the log" in out
    assert "io.roles.ROLE=TOPIC" in " ".join(_help("info", capsys, monkeypatch).split())


@pytest.mark.parametrize("verb", ["slam", "nightly", "table", "control", "simulate"])
def test_dump_config_needs_no_log(verb: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([verb, "--dump-config", "--set", "slam.mapping_interval_s=0.3"]) == 0
    assert "mapping_interval_s: 0.3" in capsys.readouterr().out


@pytest.mark.parametrize(("argv", "needs"), [(["slam"], "slam needs LOG"), (["nightly", "x"], "nightly needs LOG_DIR"),
                                             (["table"], "table needs SOURCE")])
def test_without_dump_config_the_log_is_still_required(argv: list[str], needs: str,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    assert needs in capsys.readouterr().err
