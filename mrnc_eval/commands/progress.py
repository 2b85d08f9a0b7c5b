"""A rich progress bar on a terminal, nothing otherwise (nightly jobs run unattended)."""

from __future__ import annotations

import sys
from contextlib import AbstractContextManager, nullcontext
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.progress import Progress


def progress_bar(total: int, enabled: bool = True) -> AbstractContextManager[Progress | None]:
    """Context manager yielding a rich Progress, or None when not on a terminal."""
    if not enabled or total == 0 or not sys.stderr.isatty():
        return nullcontext(None)
    from rich.progress import Progress

    return Progress(transient=True)
