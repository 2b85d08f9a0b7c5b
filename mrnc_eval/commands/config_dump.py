"""`mrnc-eval config [KEY]`: the effective configuration, or one subtree of it, as commented YAML."""

from __future__ import annotations

import dataclasses
from typing import Any

from mrnc_eval.config import Config, dump_config
from mrnc_eval.errors import UsageError
from mrnc_eval.spelling import did_you_mean


def subtree_yaml(cfg: Config, key: str | None) -> str:
    """YAML of the whole tree, or of `key` (e.g. slam.loop) nested under its parents, so the
    output still loads with --config. An unknown key names the closest existing one."""
    if not key:
        return dump_config(cfg)
    parts = [p for p in key.split(".") if p]
    node: Any = cfg
    for depth, part in enumerate(parts):
        names = [f.name for f in dataclasses.fields(node)] if dataclasses.is_dataclass(node) else []
        if part not in names:
            here = ".".join(parts[:depth])
            prefix = f"{here}." if here else ""
            raise UsageError(f"config key {key!r}: no {prefix}{part}{did_you_mean(part, names, prefix)}")
        parent, node = node, getattr(node, part)
    lines = [f"{'  ' * i}{p}:" for i, p in enumerate(parts[:-1])]
    pad = "  " * (len(parts) - 1)
    full = dump_config(parent).splitlines()[1:]  # the parent's fields, comments included
    block = _field_block(full, parts[-1])
    lines += [pad + line for line in block]
    return "# mrnc-eval effective configuration: " + key + "\n" + "\n".join(lines) + "\n"


def _field_block(lines: list[str], name: str) -> list[str]:
    """One top-level field of a dump: its comment line (sections have one), its line, its nested lines."""
    start = next(i for i, line in enumerate(lines) if line.startswith(f"{name}:"))
    end = start + 1
    while end < len(lines) and lines[end].startswith("  "):
        end += 1
    if start > 0 and lines[start - 1].startswith("#"):
        start -= 1
    return lines[start:end]
