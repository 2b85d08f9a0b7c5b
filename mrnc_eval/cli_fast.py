"""A fast path for the common `ape` and `rpe` command lines, taken by `cli.main` before typer.

Why: typer (0.29) builds a pydantic validator for every parameter of the command on each run,
~0.17 s CPU and ~6 MB for `ape`'s 15 options: a fifth of a whole 1e6-pose `ape`. The command
functions in cli.py are plain functions under their decorators, so a command line that is
plain (the verb first; REF, EST... and options declared on the function; no global options,
`--`, `--help`, repeated options or values starting with '-') is parsed here, from the same
declarations (names, types, defaults), and the function called directly. Anything else, or
anything this parser is not sure of, returns None and typer parses as before (with its errors);
tests/test_cli_fast.py holds both paths to the same calls.
"""

from __future__ import annotations

import inspect
import re
import types
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Any

from typer.models import ArgumentInfo, OptionInfo

_NUMBER = re.compile(r"[+]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")  # what float() and pydantic read alike
_INTEGER = re.compile(r"\d{1,18}")
_TRUTH_WORDS = {"true", "false", "yes", "no", "on", "off", "1", "0"}  # cli_help: `--json true` is a mistake
# Non-default settings this parser does not implement: a parameter with any of them sends the
# whole command to typer (a callback or envvar would act even when the option is not given).
_UNSUPPORTED = {"callback": None, "is_eager": False, "envvar": None, "default_factory": None, "parser": None,
                "expose_value": True, "formats": None, "clamp": False, "exists": False,
                "resolve_path": False, "allow_dash": False, "writable": False, "dir_okay": True, "file_okay": True,
                "count": False, "prompt": False, "is_flag": None, "flag_value": None, "case_sensitive": True}


@dataclass(frozen=True)
class _Param:
    """One parameter of a command function as the fast parser reads it."""

    name: str
    kind: type  # bool, int, float, str, Path or an Enum
    is_list: bool
    low: float | None = None  # typer's min= / max= of a number: a value outside goes to typer (its error)
    high: float | None = None


def _plain_type(hint: Any) -> tuple[type, bool] | None:
    """(scalar type, is a list) of an annotation, Optional removed; None when not supported."""
    args = [a for a in typing.get_args(hint) if a is not type(None)]
    if isinstance(hint, types.UnionType) or typing.get_origin(hint) is typing.Union:
        return _plain_type(args[0]) if len(args) == 1 else None
    if typing.get_origin(hint) is list:
        inner = _plain_type(args[0]) if len(args) == 1 else None
        return (inner[0], True) if inner is not None and not inner[1] else None
    if hint in (bool, int, float, str, Path) or (isinstance(hint, type) and issubclass(hint, Enum)):
        return hint, False
    return None


def _info_of(hint: Any) -> ArgumentInfo | OptionInfo | None:
    """The one typer declaration in an Annotated hint, if it uses only what this parser does."""
    meta = [m for m in getattr(hint, "__metadata__", ()) if isinstance(m, (ArgumentInfo, OptionInfo))]
    if len(meta) != 1 or any(getattr(meta[0], key, default) != default for key, default in _UNSUPPORTED.items()):
        return None
    return meta[0]


def _option_spellings(param: _Param, info: OptionInfo) -> dict[str, tuple[_Param, bool | None]] | None:
    """{spelling: (parameter, flag value or None for an option with a value)} as typer declares them."""
    decls = [str(d) for d in info.param_decls or ()]
    if info.default is not ...:  # in Annotated, Option("--json") names the option
        decls.insert(0, str(info.default))
    dashed = param.name.replace("_", "-")
    if param.is_list and param.kind is bool:
        return None
    if param.kind is not bool:
        return None if any("/" in d for d in decls) else {d: (param, None) for d in decls or [f"--{dashed}"]}
    spellings: dict[str, tuple[_Param, bool | None]] = {}
    for decl in decls or [f"--{dashed}/--no-{dashed}"]:  # typer's default flag pair
        on, _, off = decl.partition("/")
        spellings[on.strip()] = (param, True)
        if off:
            spellings[off.strip()] = (param, False)
    return spellings


def _signature(func: Callable[..., Any]) -> tuple[list[_Param], dict[str, tuple[_Param, bool | None]]] | None:
    """(arguments in order, {option spelling: (parameter, flag value or None)}), or None."""
    hints = typing.get_type_hints(func, include_extras=True)
    arguments: list[_Param] = []
    options: dict[str, tuple[_Param, bool | None]] = {}
    for name in inspect.signature(func).parameters:
        info = _info_of(hints.get(name))
        plain = None if info is None else _plain_type(typing.get_args(hints[name])[0])
        if info is None or plain is None:
            return None
        param = _Param(name, *plain, low=getattr(info, "min", None), high=getattr(info, "max", None))
        if (param.low, param.high) != (None, None) and param.kind not in (int, float):
            return None
        if isinstance(info, ArgumentInfo):
            if info.param_decls or (arguments and arguments[-1].is_list):
                return None  # a list argument only last: it takes the rest
            arguments.append(param)
            continue
        spellings = _option_spellings(param, info)
        if spellings is None:
            return None
        options.update(spellings)
    return arguments, options


def _convert(param: _Param, text: str) -> Any:
    """The value typer would pass, or raises ValueError when this parser is not sure."""
    if text.startswith("-") or not text:
        raise ValueError(text)
    if param.kind in (float, int):
        if not (_NUMBER if param.kind is float else _INTEGER).fullmatch(text):
            raise ValueError(text)
        number = param.kind(text)
        if (param.low is not None and number < param.low) or (param.high is not None and number > param.high):
            raise ValueError(text)  # out of range: typer's message
        return number
    if isinstance(param.kind, type) and issubclass(param.kind, Enum):
        return param.kind(text)  # exact spelling only (ValueError otherwise)
    if param.kind is Path:
        return Path(text)
    if param.kind is str:
        return text
    raise ValueError(text)


def _read_options(tokens: list[str], options: dict[str, tuple[_Param, bool | None]]
                  ) -> tuple[dict[str, Any], list[str]]:
    """(option values, positional tokens); ValueError when typer should parse the line."""
    values: dict[str, Any] = {}
    positional: list[str] = []
    rest = list(tokens)
    while rest:
        token = rest.pop(0)
        if not token.startswith("-"):
            positional.append(token)
            continue
        name, eq, inline = token.partition("=") if token.startswith("--") else (token, "", "")
        if name not in options or token == "--":
            raise ValueError(token)
        param, flag = options[name]
        if param.name in values and not param.is_list:
            raise ValueError(token)  # repeated: typer's rules
        if flag is not None:
            if eq or (rest and rest[0].lower() in _TRUTH_WORDS):
                raise ValueError(token)
            values[param.name] = flag
            continue
        if not eq:
            if not rest:
                raise ValueError(token)
            inline = rest.pop(0)
        if param.is_list:  # a repeatable option (--label A --label B): the values in order
            values.setdefault(param.name, []).append(_convert(param, inline))
        else:
            values[param.name] = _convert(param, inline)
    return values, positional


def fast_command(argv: Sequence[str], commands: dict[str, Callable[..., Any]]
                 ) -> tuple[Callable[..., Any], dict[str, Any]] | None:
    """(command function, keyword arguments) for a plain command line of one of `commands`,
    else None (typer parses it). Options not given take the function's own defaults."""
    if not argv or argv[0] not in commands:
        return None
    func = commands[argv[0]]
    try:
        sig = _signature(func)
    except (NameError, TypeError, AttributeError, ValueError):  # an annotation it cannot resolve: typer's
        return None
    if sig is None:
        return None
    arguments, options = sig
    try:
        values, positional = _read_options(list(argv[1:]), options)
        for param in arguments:
            taken, positional = (positional, []) if param.is_list else (positional[:1], positional[1:])
            if not taken:
                return None  # missing: typer says so
            converted = [_convert(param, t) for t in taken]
            values[param.name] = converted if param.is_list else converted[0]
    except ValueError:
        return None
    return None if positional else (func, values)
