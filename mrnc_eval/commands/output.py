"""What commands print for machines: one JSON document on stdout."""

from __future__ import annotations

import json
import sys
from typing import Any

from mrnc_eval.results import json_safe


def emit_json(obj: Any) -> None:
    """Machine output goes to stdout, one JSON document (NaN as null, numpy as plain values)."""
    sys.stdout.write(json.dumps(json_safe(obj), indent=2, sort_keys=False, allow_nan=False) + "\n")
