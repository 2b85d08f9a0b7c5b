"""Did-you-mean hints for mistyped names (configuration keys, roles, topics)."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


def did_you_mean(word: str, choices: Iterable[str], prefix: str = "") -> str:
    """' (did you mean PREFIX+X?)' for the closest choice, or '' when none is close (difflib ratio >= 0.6)."""
    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f" (did you mean {prefix}{close[0]}?)" if close else ""
