"""CLI skeleton and configuration: exit codes, lazy imports, strict YAML, overrides."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from mrnc_eval.cli import main
from mrnc_eval.config import Config, config_hash, dump_config, load_config
from mrnc_eval.errors import ConfigError

VERBS = ["info", "slam", "control", "ape", "rpe", "report", "nightly", "simulate"]


def test_help_lists_every_verb(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for verb in VERBS:
        assert verb in out


def test_help_does_not_import_heavy_modules() -> None:
    code = (
        "import sys\n"
        "from mrnc_eval.cli import main\n"
        "rc = main(['--help'])\n"
        "heavy = [m for m in ('open3d', 'gtsam', 'matplotlib', 'weasyprint', 'dask', 'scipy') if m in sys.modules]\n"
        "print(rc, heavy)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "0 []"


def test_usage_error_exit_code_is_2() -> None:
    assert main(["ape"]) == 2
    assert main(["no-such-verb"]) == 2


def test_defaults_carry_paper_values() -> None:
    cfg = Config()
    assert cfg.robot.mass_kg == 4836.0
    assert cfg.robot.max_speed_mps == 0.97


def test_yaml_roundtrip_and_override(tmp_path: Path) -> None:
    cfg = load_config(None, ["robot.track_width_m=1.9", "io.roles={lidar: /points}", "sim.imu.gyro_bias_walk=2e-5"])
    assert cfg.robot.track_width_m == 1.9
    assert cfg.sim.imu.gyro_bias_walk == 2e-5  # YAML 1.1 alone would read "2e-5" as a string
    assert cfg.io.roles == {"lidar": "/points"}
    dumped = tmp_path / "cfg.yaml"
    dumped.write_text(dump_config(cfg))
    again = load_config(dumped)
    assert again == cfg
    assert config_hash(again) == config_hash(cfg)
    assert config_hash(Config()) != config_hash(cfg)


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("robot: {no_such_key: 1}\n", "robot.no_such_key"),
        ("robot: {mass_kg: heavy}\n", "robot.mass_kg"),
        ("- a list\n", "top level must be a mapping"),
        ("robot: !!python/object/apply:os.system ['true']\n", "invalid YAML"),
    ],
)
def test_bad_config_is_rejected_with_the_key(tmp_path: Path, text: str, fragment: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=fragment.replace(".", r"\.")):
        load_config(path)


def test_config_verb_prints_loadable_yaml(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "--set", "robot.wheel_radius_m=0.4"]) == 0
    data = yaml.safe_load(capsys.readouterr().out)
    assert data["robot"]["wheel_radius_m"] == 0.4


def test_errors_are_one_line_with_control_characters_escaped(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    """A name from outside (a path here, a topic or frame name in a log) cannot forge lines or
    colour the terminal through an error message."""
    sneaky = tmp_path / "log\nmrnc-eval: all good\x1b[32m.mcap"
    assert main(["info", str(sneaky)]) == 4
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "\x1b" not in err
    assert "log\\nmrnc-eval: all good\\x1b[32m.mcap" in err


def test_an_unquoted_off_or_on_in_an_override_names_the_choice_of_a_literal() -> None:
    """YAML 1.1 reads `off` as false: `--set slam.gps.ins=off` must still pick the choice "off", while
    a bool parameter keeps the bool and a word that is no choice is still an error."""
    cfg = load_config(overrides=["slam.gps.ins=off", "slam.gps.enabled=off"])
    assert cfg.slam.gps.ins == "off"
    assert cfg.slam.gps.enabled is False
    with pytest.raises(ConfigError, match=r"slam\.gps\.track"):
        load_config(overrides=["slam.gps.track=off"])  # no choice spelled off/no/false there


@pytest.mark.parametrize("value", [None, True, False, 0, -7, 10**20, 0.0, -0.0, 0.1, -2.5, 1e17, 1e-06, 1.5e-300,
                                   5e-324, 1.7976931348623157e308, 123456789.123, float("nan"), float("inf"),
                                   float("-inf"), 3.0])
def test_config_dump_writes_numbers_as_yaml_does(value: object) -> None:
    """dump_config writes bools, None, ints and floats itself (config.yaml of every run): the
    same text yaml.safe_dump gives; anything else is left to yaml."""
    from mrnc_eval.config import plain_yaml_scalar

    by_yaml = yaml.safe_dump(value, default_flow_style=True, width=1 << 16).strip().removesuffix("...").strip()
    assert plain_yaml_scalar(value) == by_yaml
    assert yaml.safe_load(by_yaml) == value or value != value  # (nan)


def test_config_dump_leaves_strings_and_lists_to_yaml() -> None:
    from mrnc_eval.config import plain_yaml_scalar

    for value in ("yes", "1.0", "", [1, 2], (0.5,), {"a": 1}):
        assert plain_yaml_scalar(value) is None


def _by_yaml(value: object) -> str:
    return yaml.safe_dump(value, default_flow_style=True, width=1 << 16).strip().removesuffix("...").strip()


@pytest.mark.parametrize("value", ["lio", "QR", "RNG19_RFL8_SIG16_NIR16", "os_sensor", "a", "x1", "ONE", "off", "Off",
                                   "OFF", "on", "yes", "No", "true", "FALSE", "null", "Null", [1, "off"], {"a": "on"},
                                   "y", "N", "e", "E1", "NaN", "inf", "True1",
                                   "nullable", "offset", [], (), {}, (4.0, 4.0, 16.0), [1, 2.5, -0.0, None, True],
                                   {"b": 1.0, "a": "lio", "c": [1e17, 2]}, [{"y_m": -6.0, "x_m": 1.583}],
                                   {"lidar": "os_lidar"}, ((1.0, 2.0), (3.0,))])
def test_config_dump_writes_words_and_flow_collections_as_yaml_does(value: object) -> None:
    """dump_config writes plain words and lists/tuples/dicts of them and of numbers itself (yaml
    not imported by a run without a config file): the same text yaml.safe_dump gives."""
    from mrnc_eval.config import plain_yaml_flow

    assert plain_yaml_flow(value) == _by_yaml(value)


@pytest.mark.parametrize("value", ["", "1.0", "a b", "/ouster/points", "x:y", "-a", "é", {1: 2}, b"x", {2.0, 1.0}])
def test_config_dump_leaves_other_strings_and_types_to_yaml(value: object) -> None:
    """Anything not a plain word, number or collection of those: None (yaml writes it)."""
    from mrnc_eval.config import plain_yaml_flow

    assert plain_yaml_flow(value) is None


@pytest.mark.parametrize("word", ["off", "On", "YES", "no", "True", "false", "null", "NULL"])
def test_yaml_quotes_its_bool_and_null_words(word: str) -> None:
    """The negative control of the quoting: written plain, these would read back as bools or None."""
    assert _by_yaml(word) == f"'{word}'"
    assert yaml.safe_load(word) != word


def test_config_dump_of_the_defaults_needs_no_yaml_and_is_unchanged() -> None:
    """Every value of the default configuration is written without yaml, as yaml writes it."""
    from dataclasses import fields, is_dataclass

    from mrnc_eval.config import Config, as_dict, plain_yaml_flow

    def leaves(node: object) -> list[object]:
        if not is_dataclass(node):
            return [as_dict(node) if isinstance(node, (list, tuple, dict)) else node]  # as dump_config passes it
        return [x for f in fields(node) for x in leaves(getattr(node, f.name))]

    values = leaves(Config())
    assert len(values) > 300
    for v in values:
        text = plain_yaml_flow(v)
        assert text is not None, v
        assert text == _by_yaml(v)
