"""Typed errors. Library code raises these; only `cli.main` turns them into exit codes.

Exit codes (one place, `exit_code` attribute):
  0 ok, 1 a metric gate failed, 2 usage, 3 some inputs failed, 4 unreadable/invalid input or
  an output that cannot be written, 5 an internal error (a bug: the message says so).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path


class MrncError(Exception):
    """Base class of every error the CLI reports as a one-line message."""

    exit_code = 4


class UsageError(MrncError):
    """The command line or the configuration asks for something impossible."""

    exit_code = 2


class ConfigError(UsageError):
    """A configuration file or override is invalid (unknown key, wrong type)."""


class UnknownName(UsageError):
    """A name (scene, path, controller, table format...) that is not one of the choices; the
    message names what was asked and lists the choices."""

    def __init__(self, kind: str, name: str, choices: Iterable[str]) -> None:
        self.kind, self.name, self.choices = kind, name, tuple(choices)
        super().__init__(f"unknown {kind} {name!r}; choose from {', '.join(self.choices)}")


class InputError(MrncError):
    """An input file is missing, unreadable or invalid.

    The message always names the file, the topic when there is one, and the problem.
    """

    exit_code = 4

    def __init__(self, path: str | Path, problem: str, *, topic: str | None = None) -> None:
        self.path = str(path)
        self.topic = topic
        self.problem = problem
        where = f"{self.path}" + (f" [{topic}]" if topic else "")
        super().__init__(f"{where}: {problem}")


class NoGnssFix(InputError):
    """A GNSS topic holds no valid fix at all (indoors, no antenna): a property of the log, so
    commands that can do without GNSS note it and go on."""


class OutputError(MrncError):
    """An output cannot be written: it exists where a folder is needed, is not writable, the
    disk is full, or writing it would replace something the tool did not write."""

    exit_code = 4

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class EvaluationError(MrncError):
    """An evaluation cannot be computed from valid inputs (no overlap, too few matches...)."""

    exit_code = 4


class ProcessingError(MrncError):
    """A pipeline stage failed on valid input (solver failure, divergence)."""

    exit_code = 4


class SomeInputsFailed(MrncError):
    """A batch finished, but at least one of its inputs failed."""

    exit_code = 3


class GateFailed(MrncError):
    """A metric gate (APE RMSE, funnel violations...) was not met."""

    exit_code = 1


class MissingExtra(UsageError):
    """A verb needs an optional part of the installation that is not installed (the message
    names the extra: pip install 'mrnc-eval[slam]')."""

    exit_code = 2


class Interrupted(BaseException):
    """Ctrl-C (SIGINT), raised by cli.main's handler. A BaseException like KeyboardInterrupt, so
    no `except Exception` counts it as one more failed log, and not KeyboardInterrupt itself,
    which typer turns into a silent exit 130. Exit code 130 (128 + SIGINT)."""

    exit_code = 130


_interrupt_seen: list[bool] = [False]  # set by the SIGINT handler; read before any result is committed


def interrupt() -> None:
    """The SIGINT handler's body (cli.main installs it): remember the Ctrl-C, then raise."""
    _interrupt_seen[0] = True
    raise Interrupted()


def forget_interrupt() -> None:
    """A new command starts (tests call cli.main many times in one process)."""
    _interrupt_seen[0] = False


def interrupt_seen() -> bool:
    return _interrupt_seen[0]


def raise_if_interrupted() -> None:
    """Before a result or output is moved into place. Python swallows an exception raised in a
    finaliser or a generator's close ("Exception ignored in ..."), so a Ctrl-C landing there would
    let the run go on with a stage cut short and commit a partial result that looks finished."""
    if _interrupt_seen[0]:
        raise Interrupted()
