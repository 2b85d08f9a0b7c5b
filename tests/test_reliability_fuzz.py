"""Property-based fuzzing of the configuration loader (issue 15): whatever the YAML text or
the `--set` override, the loader returns a Config whose every parameter is in range, or
raises ConfigError with a short message; never another exception, never a huge message."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import fields, is_dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrnc_eval.config import Config, _bounds_for, load_config, validate_tree
from mrnc_eval.errors import ConfigError

FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _leaves(cfg: Any, where: str = "") -> list[tuple[str, Any, Any]]:
    out = []
    for f in fields(cfg):
        value = getattr(cfg, f.name)
        dotted = f"{where}.{f.name}" if where else f.name
        out += _leaves(value, dotted) if is_dataclass(value) else [(dotted, f, value)]
    return out


LEAVES = _leaves(Config())
FLOAT_KEYS = [(k, f) for k, f, v in LEAVES if isinstance(v, float)]
ALL_KEYS = [k for k, _, _ in LEAVES]

scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=30))
values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                       st.dictionaries(st.text(max_size=8), inner, max_size=4)),
                      max_leaves=12)


def _accepts(run: Callable[[], Config]) -> None:
    """`run` gives a Config whose every parameter is in range, or a short ConfigError."""
    message = ""
    try:
        cfg = run()
    except ConfigError as err:
        message = str(err)
    else:
        validate_tree(cfg)  # anything accepted is in range
    assert len(message) < 1200, message[:200]


@FUZZ
@given(key=st.sampled_from(ALL_KEYS), value=values)
def test_any_override_is_a_config_or_a_config_error(key: str, value: Any) -> None:
    raw = yaml.safe_dump(value, default_flow_style=True, width=1 << 16).strip().removesuffix("...").strip()
    _accepts(lambda: load_config(None, [f"{key}={raw}"]))


@FUZZ
@given(text=st.text(max_size=300))
def test_any_config_text_is_a_config_or_a_config_error(tmp_path: Path, text: str) -> None:
    p = tmp_path / "fuzz.yaml"
    p.write_text(text, encoding="utf-8")
    _accepts(lambda: load_config(p))


@FUZZ
@given(data=st.dictionaries(st.sampled_from(["robot", "slam", "control", "io", "gates", "sim", "x"]), values,
                            max_size=3))
def test_any_config_structure_is_a_config_or_a_config_error(tmp_path: Path, data: dict[str, Any]) -> None:
    p = tmp_path / "fuzz.yaml"
    p.write_text(yaml.safe_dump(data), encoding="utf-8")
    _accepts(lambda: load_config(p))


@FUZZ
@given(item=st.sampled_from(FLOAT_KEYS), x=st.floats(allow_nan=True, allow_infinity=True))
def test_a_float_outside_its_range_names_the_key(item: tuple[str, Any], x: float) -> None:
    key, f = item
    bounds = _bounds_for(f)
    inside = math.isfinite(x) and all({"gt": x > b, "ge": x >= b, "lt": x < b, "le": x <= b}[k]
                                      for k, b in bounds.items())
    text = repr(x) if math.isfinite(x) else ".nan" if math.isnan(x) else ".inf" if x > 0 else "-.inf"
    if inside:
        load_config(None, [f"{key}={text}"])
    else:
        with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
            load_config(None, [f"{key}={text}"])


@pytest.mark.parametrize("depth", [6, 9, 12])
def test_alias_expansion_is_bounded(tmp_path: Path, depth: int) -> None:
    lines = ["robot:", "  name:", "    - &a0 [" + ", ".join(["lol"] * 9) + "]"]
    lines += [f"    - &a{k} [{', '.join([f'*a{k - 1}'] * 9)}]" for k in range(1, depth + 1)]
    p = tmp_path / "bomb.yaml"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(ConfigError) as err:
        load_config(p)
    assert len(str(err.value)) < 400
