"""What commands print for machines: one JSON document on stdout, the same shape from every verb.

    {"schema_version": 1, "verb": "ape", "results": [{"name": ..., "stats": {...}, ...}, ...],
     "meta": {...}, "warnings": [...]}

`results` is always a list (one item per estimate, log, controller side or table cell); each
item's numbers are under `stats` (name -> number or null; NaN and infinity are null), anything
else (matching counts, findings, series) beside it. `meta` holds what belongs to the whole run
(run folder, mode, labels, definitions). The shape is the JSON Schema shipped as
mrnc_eval/schemas/output.schema.json; a breaking change raises SCHEMA_VERSION."""

from __future__ import annotations

import json
import numbers
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from mrnc_eval.results import json_safe

SCHEMA_VERSION = 1
SCHEMA_FILE = Path(__file__).resolve().parents[1] / "schemas" / "output.schema.json"


def is_stat(value: Any) -> bool:
    """A number a script can compare (bool is not one; None stands for NaN or infinity)."""
    return value is None or (isinstance(value, numbers.Real) and not isinstance(value, bool))


def item(name: str, stats: Mapping[str, Any], **rest: Any) -> dict[str, Any]:
    """One entry of `results`: its name, its numbers under `stats`, the rest beside them."""
    clean = {k: _number(v) for k, v in stats.items()}
    bad = [k for k, v in clean.items() if not is_stat(v)]
    if bad:  # a programming error: stats are numbers only
        raise TypeError(f"stats of {name!r} hold non-numbers: {', '.join(bad)}")
    return {"name": name, "stats": clean, **rest}


def _number(value: Any) -> Any:
    """A stat as plain JSON: numpy scalars as Python ones, NaN and infinity as null (json_safe
    writes infinity as "inf", which is not a number)."""
    value = json_safe(value)
    return None if isinstance(value, str) and value in ("inf", "-inf") else value


def split_stats(values: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """(numbers, everything else) of a flat summary dictionary."""
    stats = {k: v for k, v in values.items() if is_stat(v)}
    return stats, {k: v for k, v in values.items() if k not in stats}


def document(verb: str, results: Iterable[Mapping[str, Any]], *, meta: Mapping[str, Any] | None = None,
             warnings: Iterable[str] = ()) -> dict[str, Any]:
    """The --json document of `verb`."""
    return json_safe({"schema_version": SCHEMA_VERSION, "verb": verb, "results": list(results),
                      "meta": dict(meta or {}), "warnings": [str(w) for w in warnings]})


def emit_json(verb: str, results: Iterable[Mapping[str, Any]], *, meta: Mapping[str, Any] | None = None,
              warnings: Iterable[str] = ()) -> None:
    """Machine output goes to stdout, one JSON document (NaN as null, numpy as plain values)."""
    emit_document(document(verb, results, meta=meta, warnings=warnings))


def emit_document(doc: Mapping[str, Any]) -> None:
    """Print a document built by `document`."""
    sys.stdout.write(json.dumps(doc, indent=2, sort_keys=False, allow_nan=False) + "\n")


def schema() -> dict[str, Any]:
    """The JSON Schema every --json document validates against."""
    loaded: dict[str, Any] = json.loads(SCHEMA_FILE.read_text(encoding="utf-8"))
    return loaded
