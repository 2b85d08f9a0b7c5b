"""`param()`: a dataclass field that carries its help text, unit and valid range.

Domain config dataclasses (slam/config.py, control/config.py, ...) declare every
parameter with `param(default, "help", unit="m")`; the help and unit are used by
`mrnc-eval config` and in reports, so a parameter is documented where it is defined.
A range (`gt=0`, `ge=0`, `le=1`, ...) or a `check` callable is declared the same way and
enforced centrally by `config.build` (a bad value is a one-line exit-2 error naming the key);
parameters without a declaration get the rules of `config.RANGE_RULES` by name, and every
float must be finite unless `finite=False`.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import field
from typing import Any

Check = Callable[[Any], "str | None"]  # returns the problem, or None when the value is valid


def param(default: Any, help: str, unit: str = "", *, gt: float | None = None, ge: float | None = None,
          lt: float | None = None, le: float | None = None, finite: bool = True, check: Check | None = None,
          interval: bool | None = None) -> Any:
    """A documented config field. Mutable defaults (lists, dicts) are copied per instance.
    Bounds apply to a number and to every number of a list or tuple. `interval`: a [low, high]
    pair that must not be reversed (default: a numeric pair whose default is ascending)."""
    metadata = {"help": help, "unit": unit, "finite": finite, "check": check,
                **({"interval": interval} if interval is not None else {}),
                "bounds": {k: v for k, v in (("gt", gt), ("ge", ge), ("lt", lt), ("le", le)) if v is not None}}
    if isinstance(default, (list, dict, set)):
        return field(default_factory=lambda: copy.deepcopy(default), metadata=metadata)
    if hasattr(default, "__dataclass_fields__"):
        return field(default_factory=lambda: copy.deepcopy(default), metadata=metadata)
    return field(default=default, metadata=metadata)


def section(cls: type, help: str = "") -> Any:
    """A nested config section with its own defaults."""
    return field(default_factory=cls, metadata={"help": help, "unit": ""})
