"""The effective configuration: one typed tree of frozen dataclasses.

Each domain owns its section (`slam/config.py`, `control/config.py`, `sim/config.py`,
`evaluation/config.py`); this module composes them and provides strict YAML loading
(safe loader, unknown keys rejected), per-run overrides (`--set a.b=value`), a
commented YAML dump and a stable hash for provenance.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import types
import typing
from dataclasses import dataclass, fields, is_dataclass
from pathlib import Path
from typing import Any, Literal, TypeVar, get_args, get_origin

import yaml

from mrnc_eval.control.config import ControlConfig
from mrnc_eval.errors import ConfigError
from mrnc_eval.evaluation.config import EvaluationConfig, GatesConfig
from mrnc_eval.io.config import IoConfig
from mrnc_eval.params import param, section
from mrnc_eval.sim.config import SimConfig
from mrnc_eval.slam.config import SlamConfig

T = TypeVar("T")


@dataclass(frozen=True)
class RobotConfig:
    """The machine of the paper ("MPD", skid-steer, hydraulic in-wheel drives)."""

    name: str = param("MPD", "robot name shown in reports")
    mass_kg: float = param(4836.0, "vehicle mass", "kg")
    length_m: float = param(4.0, "body length", "m")
    width_m: float = param(2.0, "body width", "m")
    height_m: float = param(1.5, "body height", "m")
    max_speed_mps: float = param(0.97, "maximum forward speed of the machine", "m/s")
    wheel_radius_m: float = param(0.35, "wheel radius (assumed; not in the paper)", "m")
    track_width_m: float = param(
        1.6,
        "effective track width Lr used by inverse kinematics; NOT given in the paper, "
        "an assumption (geometric track times ICR expansion factor)",
        "m",
    )


@dataclass(frozen=True)
class Config:
    """Every parameter of the paper, the SLAM, the controllers, the simulator and the gates."""

    robot: RobotConfig = section(RobotConfig, "robot geometry and limits")
    io: IoConfig = section(IoConfig, "log reading: topic roles, GNSS origin")
    slam: SlamConfig = section(SlamConfig, "LIO-SAM-style SLAM replay")
    control: ControlConfig = section(ControlConfig, "pure pursuit, kinematics, controllers, plant, metrics")
    evaluation: EvaluationConfig = section(EvaluationConfig, "trajectory evaluation defaults")
    gates: GatesConfig = section(GatesConfig, "pass/fail gates of reports and the nightly job")
    sim: SimConfig = section(SimConfig, "synthetic log generator")


# ---------------------------------------------------------------- building from data


def _coerce(value: Any, tp: Any, where: str) -> Any:
    origin = get_origin(tp)
    if tp is Any:
        return value
    if is_dataclass(tp):
        if not isinstance(value, dict):
            raise ConfigError(f"{where}: expected a mapping, got {type(value).__name__}")
        return build(tp, value, where)
    if origin is Literal:
        if value not in get_args(tp):
            raise ConfigError(f"{where}: {value!r} is not one of {list(get_args(tp))}")
        return value
    if origin in (typing.Union, types.UnionType):
        args = get_args(tp)
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _coerce(value, arg, where)
            except ConfigError as err:
                errors.append(str(err))
        raise ConfigError(errors[0] if errors else f"{where}: invalid value {value!r}")
    if origin in (tuple, list):
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{where}: expected a list, got {value!r}")
        args = get_args(tp)
        if origin is tuple and args and args[-1] is not Ellipsis:
            if len(args) != len(value):
                raise ConfigError(f"{where}: expected {len(args)} items, got {len(value)}")
            items = [_coerce(v, a, f"{where}[{i}]") for i, (v, a) in enumerate(zip(value, args, strict=True))]
        else:
            item_tp = args[0] if args else Any
            items = [_coerce(v, item_tp, f"{where}[{i}]") for i, v in enumerate(value)]
        return tuple(items) if origin is tuple else items
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(f"{where}: expected a mapping, got {value!r}")
        key_tp, val_tp = get_args(tp) or (Any, Any)
        return {_coerce(k, key_tp, where): _coerce(v, val_tp, f"{where}.{k}") for k, v in value.items()}
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: expected true/false, got {value!r}")
        return value
    if tp is float:
        if isinstance(value, str):  # YAML 1.1 reads exponents without a dot ("1e-4") as strings
            with contextlib.suppress(ValueError):
                value = float(value)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{where}: expected a number, got {value!r}")
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: expected an integer, got {value!r}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected a string, got {value!r}")
        return value
    raise ConfigError(f"{where}: unsupported config type {tp!r}")


def build(cls: type[T], data: dict[str, Any], where: str = "") -> T:
    """Build dataclass `cls` from a mapping; missing keys keep defaults, unknown keys fail."""
    hints = typing.get_type_hints(cls)
    known = {f.name for f in fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(data) - known)
    if unknown:
        prefix = f"{where}." if where else ""
        raise ConfigError(f"unknown config key(s): {', '.join(prefix + k for k in unknown)}")
    kwargs = {
        key: _coerce(value, hints[key], f"{where}.{key}" if where else key)
        for key, value in data.items()
    }
    return cls(**kwargs)


def as_dict(cfg: Any) -> dict[str, Any]:
    """Plain nested dict (tuples become lists) for YAML/JSON."""
    def plain(v: Any) -> Any:
        if is_dataclass(v):
            return {f.name: plain(getattr(v, f.name)) for f in fields(v)}
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        return v

    return plain(cfg)


def _deep_merge(base: dict[str, Any], extra: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in extra.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _deep_merge(out[key], value)
        else:
            out[key] = value
    return out


def parse_override(text: str) -> dict[str, Any]:
    """`control.raid.beta=1.5` -> {"control": {"raid": {"beta": 1.5}}}; value parsed as YAML."""
    if "=" not in text:
        raise ConfigError(f"override {text!r}: expected KEY=VALUE, e.g. control.raid.beta=1.5")
    key, raw = text.split("=", 1)
    try:
        value = yaml.safe_load(raw) if raw.strip() else ""
    except yaml.YAMLError as err:
        raise ConfigError(f"override {text!r}: value is not valid YAML: {err}") from err
    node: dict[str, Any] = {}
    cursor = node
    parts = [p for p in key.strip().split(".") if p]
    if not parts:
        raise ConfigError(f"override {text!r}: empty key")
    for part in parts[:-1]:
        cursor[part] = {}
        cursor = cursor[part]
    cursor[parts[-1]] = value
    return node


def load_config(path: str | Path | None = None, overrides: typing.Sequence[str] = ()) -> Config:
    """Defaults, then the YAML file (safe loader), then `KEY=VALUE` overrides in order."""
    data: dict[str, Any] = {}
    if path is not None:
        p = Path(path)
        try:
            text = p.read_text(encoding="utf-8")
        except OSError as err:
            raise ConfigError(f"{p}: cannot read config: {err.strerror or err}") from err
        try:
            loaded = yaml.safe_load(text)
        except yaml.YAMLError as err:
            raise ConfigError(f"{p}: invalid YAML: {err}") from err
        if loaded is None:
            loaded = {}
        if not isinstance(loaded, dict):
            raise ConfigError(f"{p}: the top level must be a mapping")
        data = loaded
    for text in overrides:
        data = _deep_merge(data, parse_override(text))
    try:
        return build(Config, data)
    except ConfigError as err:
        where = f"{path}: " if path is not None else ""
        raise ConfigError(f"{where}{err}") from err


CONFIG_FILE_NAME = "config.yaml"


def config_hash(cfg: Any) -> str:
    """Short stable hash of the effective configuration (provenance in reports and history)."""
    blob = json.dumps(as_dict(cfg), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def dump_config(cfg: Any) -> str:
    """YAML with each parameter's help text and unit as a comment."""
    lines: list[str] = ["# mrnc-eval effective configuration"]

    def scalar(v: Any) -> str:
        return yaml.safe_dump(v, default_flow_style=True, width=1 << 16).strip().removesuffix("...").strip()

    def walk(obj: Any, indent: int) -> None:
        pad = "  " * indent
        for f in fields(obj):
            value = getattr(obj, f.name)
            help_text = f.metadata.get("help", "")
            unit = f.metadata.get("unit", "")
            comment = help_text + (f" [{unit}]" if unit else "")
            if is_dataclass(value):
                if comment:
                    lines.append(f"{pad}# {comment}")
                lines.append(f"{pad}{f.name}:")
                walk(value, indent + 1)
            else:
                rendered = scalar(as_dict(value) if isinstance(value, (tuple, list, dict)) else value)
                lines.append(f"{pad}{f.name}: {rendered}" + (f"  # {comment}" if comment else ""))

    walk(cfg, 0)
    return "\n".join(lines) + "\n"


def replace_path(cfg: T, dotted: str, value: Any) -> T:
    """Functional update of one nested field, e.g. replace_path(cfg, "slam.loop.enabled", False)."""
    head, _, rest = dotted.partition(".")
    if not rest:
        return dataclasses.replace(cfg, **{head: value})  # type: ignore[type-var]
    return dataclasses.replace(cfg, **{head: replace_path(getattr(cfg, head), rest, value)})  # type: ignore[type-var]
