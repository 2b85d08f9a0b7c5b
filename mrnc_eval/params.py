"""`param()`: a dataclass field that carries its help text and unit.

Domain config dataclasses (slam/config.py, control/config.py, ...) declare every
parameter with `param(default, "help", unit="m")`; the help and unit are used by
`mrnc-eval config` and in reports, so a parameter is documented where it is defined.
"""

from __future__ import annotations

import copy
from dataclasses import field
from typing import Any


def param(default: Any, help: str, unit: str = "") -> Any:
    """A documented config field. Mutable defaults (lists, dicts) are copied per instance."""
    metadata = {"help": help, "unit": unit}
    if isinstance(default, (list, dict, set)):
        return field(default_factory=lambda: copy.deepcopy(default), metadata=metadata)
    if hasattr(default, "__dataclass_fields__"):
        return field(default_factory=lambda: copy.deepcopy(default), metadata=metadata)
    return field(default=default, metadata=metadata)


def section(cls: type, help: str = "") -> Any:
    """A nested config section with its own defaults."""
    return field(default_factory=cls, metadata={"help": help, "unit": ""})
