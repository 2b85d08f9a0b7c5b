"""The one sanitiser for text that comes from log content or user input and is printed.

`printable` makes one terminal line of any text (newlines, ANSI escapes and other control
characters are shown escaped, so a topic name cannot forge or colour our output);
`html_text` does the same for HTML reports (Jinja's autoescaping handles <, >, &);
`shorten` bounds how much of a value an error message shows (a hostile value may be huge).
"""

from __future__ import annotations

import logging
import reprlib
from typing import Any

MAX_SHOWN = 200  # characters of a value shown in a message

_repr = reprlib.Repr()
_repr.maxlevel = 3  # bounded work, whatever the nesting (a YAML alias bomb)
_repr.maxlist = _repr.maxtuple = _repr.maxdict = _repr.maxset = 6
_repr.maxstring = _repr.maxother = MAX_SHOWN
_repr.maxlong = 40


def printable(text: str) -> str:
    """One terminal line: control characters are shown escaped (\\n, \\x1b)."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def html_text(value: Any) -> Any:
    """For HTML (a Jinja `finalize`): control characters other than newline and tab shown
    escaped, as on the terminal; markup we produced ourselves (Markup) and non-text untouched."""
    if not isinstance(value, str) or hasattr(value, "__html__"):
        return value
    return "".join(c if c.isprintable() or c in "\n\t" else repr(c)[1:-1] for c in value)


def shorten(value: Any, limit: int = MAX_SHOWN) -> str:
    """A bounded, printable repr of `value` for error messages (at most ~`limit` characters)."""
    text = printable(_repr.repr(value))
    return text if len(text) <= limit else text[: limit - 3] + "..."


class PrintableFormatter(logging.Formatter):
    """The log handler's formatter (cli installs it): every message, whatever module logs it and
    whatever log text (topic names, frame ids, file names) it carries, passes through `printable`,
    and so do traceback lines (--debug); one escaping, in one place, for all of stderr's lines."""

    def formatMessage(self, record: logging.LogRecord) -> str:
        record.message = printable(record.message)
        return super().formatMessage(record)

    def formatException(self, ei: Any) -> str:
        return "\n".join(printable(line) for line in super().formatException(ei).splitlines())


def install_log_format(level: int, stream: Any) -> None:
    """Route the package's log records (and any library's) to `stream` through PrintableFormatter.
    -v/-vv (`level` INFO/DEBUG) open the package's own records; libraries (numba, matplotlib)
    stay at WARNING, so -vv shows our stages, not a compiler's trace."""
    handler = logging.StreamHandler(stream)
    handler.setFormatter(PrintableFormatter("%(levelname)s %(name)s: %(message)s"))
    logging.basicConfig(level=max(level, logging.WARNING), handlers=[handler], force=True)
    logging.getLogger("mrnc_eval").setLevel(level)


OFF_TERMINAL_WIDTH = 10_000  # columns: piped or redirected output is never cut (rich would assume 80)


def console(**options: Any) -> Any:
    """The rich Console every verb prints tables with: the terminal's width on a terminal; off a
    terminal (`> file`, `| cat`) wide enough that no column is cut to `Sett…` or `0.0…`."""
    from rich.console import Console

    out = Console(**options)
    return out if out.is_terminal else Console(width=OFF_TERMINAL_WIDTH, **options)
