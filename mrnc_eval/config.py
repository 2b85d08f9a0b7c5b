"""The effective configuration: one typed tree of frozen dataclasses.

Each domain owns its section (`slam/config.py`, `control/config.py`, `sim/config.py`,
`evaluation/config.py`); this module composes them and provides strict YAML loading
(safe loader, unknown and duplicate keys rejected, size and alias expansion bounded, UTF-8
only), range validation of every parameter (declared with `param(..., gt=0)` or by the name
rules below), per-run overrides (`--set a.b=value`), a commented YAML dump and a stable
hash for provenance. Every problem is a one-line ConfigError naming the key; values are
shown shortened (`text.shorten`), never expanded.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import json
import math
import re
import types
import typing
from dataclasses import Field, dataclass, fields, is_dataclass
from pathlib import Path
from typing import Any, Literal, TypeVar, get_args, get_origin

from mrnc_eval.control.config import ControlConfig
from mrnc_eval.errors import ConfigError, InputError
from mrnc_eval.evaluation.config import EvaluationConfig, GatesConfig
from mrnc_eval.io.config import IoConfig
from mrnc_eval.params import param, section
from mrnc_eval.sim.config import SimConfig
from mrnc_eval.slam.config import SlamConfig
from mrnc_eval.spelling import did_you_mean
from mrnc_eval.text import shorten

T = TypeVar("T")


@dataclass(frozen=True)
class RobotConfig:
    """The machine of the paper ("MPD", skid-steer, hydraulic in-wheel drives)."""

    name: str = param("MPD", "robot name shown in reports")
    mass_kg: float = param(4836.0, "vehicle mass", "kg", gt=0)
    length_m: float = param(4.0, "body length", "m", gt=0)
    width_m: float = param(2.0, "body width", "m", gt=0)
    height_m: float = param(1.5, "body height", "m", gt=0)
    max_speed_mps: float = param(0.97, "maximum forward speed of the machine", "m/s", gt=0)
    wheel_radius_m: float = param(0.35, "wheel radius (assumed; not in the paper)", "m", gt=0)
    track_width_m: float = param(
        1.6,
        "effective track width Lr used by inverse kinematics; NOT given in the paper, "
        "an assumption (geometric track times ICR expansion factor)",
        "m",
        gt=0,
    )


@dataclass(frozen=True)
class NightlyConfig:
    """The unattended job (`mrnc-eval nightly`)."""

    scheduler_timeout_s: float = param(5.0, "how long to wait for the Dask scheduler of --scheduler to answer", "s",
                                       gt=0.0)


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
    nightly: NightlyConfig = section(NightlyConfig, "the nightly job")


# ---------------------------------------------------------------- building from data


_YAML_BOOLS = {True: ("on", "yes", "true", "y"), False: ("off", "no", "false", "n")}


def _coerce(value: Any, tp: Any, where: str) -> Any:
    """`value` as type `tp`, or a ConfigError naming `where` (the dotted key)."""
    origin = get_origin(tp)
    if tp is Any:
        return value
    if isinstance(tp, type) and is_dataclass(tp):
        if not isinstance(value, dict):
            raise ConfigError(f"{where}: expected a mapping, got {type(value).__name__}")
        return build(tp, value, where)
    if origin is Literal:
        if isinstance(value, bool) and value not in get_args(tp):  # YAML 1.1: an unquoted off/on/no/yes
            value = next((c for c in get_args(tp) if isinstance(c, str) and c.lower() in _YAML_BOOLS[value]), value)
        if value not in get_args(tp):
            raise ConfigError(f"{where}: {shorten(value)} is not one of {list(get_args(tp))}")
        return value
    if origin in (typing.Union, types.UnionType):
        return _coerce_union(value, get_args(tp), where)
    if origin in (tuple, list):
        return _coerce_sequence(value, origin, get_args(tp), where)
    if origin is dict:
        return _coerce_mapping(value, get_args(tp), where)
    return _coerce_scalar(value, tp, where)


def _coerce_union(value: Any, args: tuple[Any, ...], where: str) -> Any:
    """The first member type that accepts `value`; the first member's error otherwise."""
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
    raise ConfigError(errors[0] if errors else f"{where}: invalid value {shorten(value)}")


def _coerce_sequence(value: Any, origin: type, args: tuple[Any, ...], where: str) -> Any:
    """A list, a fixed-length tuple or a variable-length tuple, item by item."""
    if not isinstance(value, (list, tuple)):
        raise ConfigError(f"{where}: expected a list, got {shorten(value)}")
    if origin is tuple and args and args[-1] is not Ellipsis:
        if len(args) != len(value):
            raise ConfigError(f"{where}: expected {len(args)} items, got {len(value)}")
        items = [_coerce(v, a, f"{where}[{i}]") for i, (v, a) in enumerate(zip(value, args, strict=True))]
    else:
        item_tp = args[0] if args else Any
        items = [_coerce(v, item_tp, f"{where}[{i}]") for i, v in enumerate(value)]
    return tuple(items) if origin is tuple else items


def _coerce_mapping(value: Any, args: tuple[Any, ...], where: str) -> dict[Any, Any]:
    if not isinstance(value, dict):
        raise ConfigError(f"{where}: expected a mapping, got {shorten(value)}")
    key_tp, val_tp = args or (Any, Any)
    return {_coerce(k, key_tp, where): _coerce(v, val_tp, f"{where}.{shorten(k, 60)}") for k, v in value.items()}


def _coerce_scalar(value: Any, tp: Any, where: str) -> Any:
    """bool, float, int or str; bools are never numbers, and YAML's "1e-4" strings are floats."""
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: expected true/false, got {shorten(value)}")
        return value
    if tp is float:
        if isinstance(value, str):  # YAML 1.1 reads exponents without a dot ("1e-4") as strings
            with contextlib.suppress(ValueError):
                value = float(value)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{where}: expected a number, got {shorten(value)}")
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: expected an integer, got {shorten(value)}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected a string, got {shorten(value)}")
        return value
    raise ConfigError(f"{where}: unsupported config type {tp!r}")


def build(cls: type[T], data: dict[str, Any], where: str = "") -> T:
    """Build dataclass `cls` from a mapping; missing keys keep defaults, unknown keys fail,
    every given value is checked against its parameter's range."""
    hints = typing.get_type_hints(cls)
    by_name = {f.name: f for f in fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(str(k) for k in set(data) - set(by_name))
    if unknown:
        prefix = f"{where}." if where else ""
        named = (shorten(prefix + k) + did_you_mean(k, by_name, prefix) for k in unknown)  # quote the key only
        raise ConfigError(f"unknown config key(s): {', '.join(named)}")
    kwargs = {}
    for key, value in data.items():
        dotted = f"{where}.{key}" if where else key
        kwargs[key] = _coerce(value, hints[key], dotted)
        _check_range(kwargs[key], by_name[key], dotted)
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as err:  # a section's own __post_init__ check
        raise ConfigError(f"{where or 'config'}: {shorten(str(err))}") from err


# ---------------------------------------------------------------- ranges

# Rules for parameters that declare no range, by name (the units say what is physical):
# rates, masses, sizes of leaves and radii are positive; noises, variances, thresholds and
# durations are not negative; ratios, fractions and probabilities lie in [0, 1].
RANGE_RULES: tuple[tuple[re.Pattern[str], dict[str, float]], ...] = (
    (re.compile(r"(^|_)(fraction|probability)$|_ratio(_max)?$|^parallel_ratio$"), {"ge": 0.0, "le": 1.0}),
    (re.compile(r"^(rate_hz|gravity|scene_scale|tau_s|tau_hat_s|lookahead_m)$|_leaf_m$|voxel|radius"), {"gt": 0.0}),
    (re.compile(r"_hz$|_kg$|_mb$|noise|_walk$|sigma|variance|_m2$|threshold|_range_m$|^max_|^min_|_max$"
                r"|(delay|gap|window|horizon|hold|interval|time)_s$"), {"ge": 0.0}),
)
_BOUND_TEXT = {"gt": ">", "ge": ">=", "lt": "<", "le": "<="}


def _bounds_for(f: Field[Any]) -> dict[str, float]:
    declared = f.metadata.get("bounds")
    if declared:
        return dict(declared)
    if "offset" in f.name:
        return {}
    return next((dict(b) for pattern, b in RANGE_RULES if pattern.search(f.name)), {})


def _is_interval(f: Field[Any]) -> bool:
    """A [low, high] parameter: declared with interval=True, or a numeric pair whose default is
    ascending (draw ranges such as control.sweep.delay_s [0.02, 0.08]; a point such as
    control.scenario.centre_xy_m has no order)."""
    if "interval" in f.metadata:
        return bool(f.metadata["interval"])
    default = f.default_factory() if callable(f.default_factory) else f.default
    pair = _numbers(default) if isinstance(default, (list, tuple)) and len(default) == 2 else []
    return len(pair) == 2 and pair[0] < pair[1]


def _numbers(value: Any) -> list[float]:
    if isinstance(value, bool):
        return []
    if isinstance(value, (int, float)):
        return [float(value)]
    if isinstance(value, (list, tuple)):
        return [x for v in value for x in _numbers(v)]
    return []


def _check_range(value: Any, f: Field[Any], where: str) -> None:
    """One parameter against its declared (or name-rule) range, finiteness and check."""
    if is_dataclass(value):
        return  # a section: its fields were checked as they were built
    for x in _numbers(value):
        if f.metadata.get("finite", True) and not math.isfinite(x):
            raise ConfigError(f"{where}: {shorten(value)} is not a finite number")
        for kind, bound in _bounds_for(f).items():
            ok = {"gt": x > bound, "ge": x >= bound, "lt": x < bound, "le": x <= bound}[kind]
            if not ok:
                raise ConfigError(f"{where}: {shorten(value)} is out of range (must be {_BOUND_TEXT[kind]} {bound:g})")
    if _is_interval(f) and isinstance(value, (list, tuple)) and len(_numbers(value)) == 2:
        lo, hi = _numbers(value)
        if lo > hi:
            raise ConfigError(f"{where}: {shorten(value)} is a reversed range (write [low, high])")
    check = f.metadata.get("check")
    problem = check(value) if check is not None else None
    if problem:
        raise ConfigError(f"{where}: {shorten(value)}: {problem}")


def validate_tree(cfg: Any, where: str = "") -> None:
    """Check every parameter of a built config (defaults included) against its range."""
    for f in fields(cfg):
        value = getattr(cfg, f.name)
        dotted = f"{where}.{f.name}" if where else f.name
        if is_dataclass(value):
            validate_tree(value, dotted)
        else:
            _check_range(value, f, dotted)


# ---------------------------------------------------------------- bounded YAML

MAX_YAML_BYTES = 1_000_000  # a configuration is a few kB; anything this big is a mistake or an attack
MAX_YAML_NODES = 100_000  # nodes after alias expansion (a "billion laughs" file is rejected, not expanded)


@functools.cache
def _strict_loader() -> Any:
    """The safe loader that rejects duplicate keys (the second would silently win); made on first
    use, so a run without a config file or --set never imports yaml."""
    import yaml

    class StrictLoader(yaml.SafeLoader):  # type: ignore[misc]  # PyYAML ships no types here
        def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
            seen: set[tuple[str, str]] = set()
            for key_node, _ in node.value:
                if isinstance(key_node, yaml.ScalarNode):
                    key = (key_node.tag, key_node.value)
                    if key in seen:
                        raise yaml.constructor.ConstructorError(
                            None, None, f"duplicate key {shorten(key_node.value, 80)}", key_node.start_mark)
                    seen.add(key)
            return super().construct_mapping(node, deep=deep)

    return StrictLoader


def _expanded_size(node: Any, memo: dict[int, int], active: set[int]) -> int:
    """Number of nodes the document has once every alias is expanded (memoised: O(distinct nodes))."""
    import yaml

    if id(node) in memo:
        return memo[id(node)]
    if id(node) in active:
        raise ConfigError("recursive YAML alias")
    active.add(id(node))
    if isinstance(node, yaml.SequenceNode):
        size = 1 + sum(_expanded_size(child, memo, active) for child in node.value)
    elif isinstance(node, yaml.MappingNode):
        size = 1 + sum(_expanded_size(k, memo, active) + _expanded_size(v, memo, active) for k, v in node.value)
    else:
        size = 1
    active.discard(id(node))
    memo[id(node)] = min(size, MAX_YAML_NODES + 1)
    return memo[id(node)]


def load_yaml(text: str, where: str) -> Any:
    """Parse YAML text with the strict, bounded loader; every problem is a one-line ConfigError."""
    import yaml

    if len(text) > MAX_YAML_BYTES:
        raise ConfigError(f"{where}: YAML larger than {MAX_YAML_BYTES // 1000} kB")
    try:
        loader = _strict_loader()(text)  # the reader already rejects control characters
    except yaml.YAMLError as err:
        raise ConfigError(f"{where}: invalid YAML: {shorten(' '.join(str(err).split()), 300)}") from err
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        if _expanded_size(node, {}, set()) > MAX_YAML_NODES:
            raise ConfigError(f"{where}: YAML expands to more than {MAX_YAML_NODES} nodes (aliases); refused")
        return loader.construct_document(node)
    except yaml.YAMLError as err:
        raise ConfigError(f"{where}: invalid YAML: {shorten(' '.join(str(err).split()), 300)}") from err
    except RecursionError as err:
        raise ConfigError(f"{where}: YAML nested too deeply") from err
    finally:
        loader.dispose()


def load_yaml_file(path: str | Path, what: str = "config") -> Any:
    """A YAML file: size-limited, UTF-8, strict and bounded (see load_yaml)."""
    p = Path(path)
    try:
        if p.stat().st_size > MAX_YAML_BYTES:
            raise ConfigError(f"{p}: {what} file larger than {MAX_YAML_BYTES // 1000} kB")
        text = p.read_bytes().decode("utf-8")
    except UnicodeDecodeError as err:
        raise ConfigError(f"{p}: {what} file is not UTF-8 text (byte {err.start})") from err
    except OSError as err:  # a file that cannot be read is exit 4, like every unreadable input
        raise InputError(p, f"cannot read {what} file: {err.strerror or err}") from err
    return load_yaml(text, str(p))


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
        raise ConfigError(f"override {shorten(text)}: expected KEY=VALUE, e.g. control.raid.beta=1.5")
    key, raw = text.split("=", 1)
    value = load_yaml(raw, f"override {shorten(key, 80)}") if raw.strip() else ""
    node: dict[str, Any] = {}
    cursor = node
    parts = [p for p in key.strip().split(".") if p]
    if not parts:
        raise ConfigError(f"override {shorten(text)}: empty key")
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
        loaded = load_yaml_file(p)
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


def plain_yaml_scalar(v: Any) -> str | None:
    """yaml.safe_dump's text of a bool, None, int or float (its SafeRepresenter's rules), made
    without a dumper (~25 us each, ~10 ms for a whole config); None for anything else."""
    if v is None:
        return "null"
    if type(v) is bool:
        return "true" if v else "false"
    if type(v) is int:
        return str(v)
    if type(v) is not float:
        return None
    if math.isnan(v):
        return ".nan"
    if math.isinf(v):
        return ".inf" if v > 0 else "-.inf"
    text = repr(v).lower()
    return text.replace("e", ".0e", 1) if "." not in text and "e" in text else text  # 1e17 -> 1.0e17, as yaml


_PLAIN_WORD = re.compile(r"[A-Za-z][A-Za-z0-9_]*")  # a str safe_dump leaves unquoted, unless a YAML 1.1 word below
_YAML_WORDS = {w for word in ("yes", "no", "true", "false", "on", "off", "null")
               for w in (word, word.capitalize(), word.upper())}  # PyYAML's bool and null resolvers


def plain_yaml_flow(v: Any) -> str | None:
    """yaml.safe_dump(v, default_flow_style=True)'s text (stripped) of a scalar (plain_yaml_scalar),
    a word-like str (single-quoted when YAML 1.1 reads it as a bool or null: 'off'), or a list,
    tuple or dict (keys sorted, as safe_dump sorts them) of those, made without yaml (whose import
    is ~6 ms of a `slam` run's start); None for anything else (a str that is not a plain word, any
    other type): ask yaml then."""
    if isinstance(v, str):
        if type(v) is not str or not _PLAIN_WORD.fullmatch(v):
            return None
        return f"'{v}'" if v in _YAML_WORDS else v  # quoted, or it would read back as a bool or null
    if type(v) in (list, tuple):
        items = [plain_yaml_flow(x) for x in v]
        return None if None in items else "[" + ", ".join(typing.cast(list[str], items)) + "]"
    if type(v) is dict:
        if not all(type(k) is str for k in v):
            return None
        pairs = [(plain_yaml_flow(k), plain_yaml_flow(v[k])) for k in sorted(v)]
        if any(a is None or b is None for a, b in pairs):
            return None
        return "{" + ", ".join(f"{a}: {b}" for a, b in pairs) + "}"
    return plain_yaml_scalar(v)


def dump_config(cfg: Any) -> str:
    """YAML with each parameter's help text and unit as a comment."""
    lines: list[str] = ["# mrnc-eval effective configuration"]

    def scalar(v: Any) -> str:
        plain = plain_yaml_flow(v)
        if plain is not None:
            return plain
        import yaml

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


def replace_paths(cfg: T, values: typing.Mapping[str, Any]) -> T:
    """replace_path for each dotted key of `values`, in order."""
    for dotted, value in values.items():
        cfg = replace_path(cfg, dotted, value)
    return cfg


def replace_path(cfg: T, dotted: str, value: Any) -> T:
    """Functional update of one nested field, e.g. replace_path(cfg, "slam.loop.enabled", False)."""
    head, _, rest = dotted.partition(".")
    if not rest:
        return dataclasses.replace(cfg, **{head: value})  # type: ignore[type-var]
    return dataclasses.replace(cfg, **{head: replace_path(getattr(cfg, head), rest, value)})  # type: ignore[type-var]
