"""How the command line reads and shows itself: plain metavars, listed choices, one example per
verb, global options accepted after the verb, and flags that refuse a stray value.

typer shows every parameter's Python type (`<bool>`, `<list[str]>`, `{LOG...}...`), which makes
flags look as if they took a value; the classes here print what a user types instead. Kept apart
from `cli.py` so the verbs stay one thin function each.
"""

from __future__ import annotations

import inspect
import itertools
import re
from pathlib import Path
from typing import Any

from typer import _click as click  # typer vendors its own click since 0.2x; its contexts are these
from typer._click.exceptions import UsageError
from typer.core import TyperArgument, TyperCommand, TyperGroup, TyperOption

# One example per verb, shown under its --help (and in the README's verb table).
EXAMPLES: dict[str, tuple[str, ...]] = {
    "config": ("mrnc-eval config slam.loop", "mrnc-eval config --set control.raid.beta=1.5 > my.yaml"),
    "info": ("mrnc-eval info sample_logs/loop_forest.bag",),
    "slam": ("mrnc-eval slam sample_logs/loop_forest.bag --method lio --out results",),
    "control": ("mrnc-eval control sample_logs/loop_forest.bag --mode replay",
                "mrnc-eval control robot_run.mcap --path plan.tum"),
    "ape": ("mrnc-eval ape sample_logs/loop_forest.gt.tum results/latest/trajectory.tum --align se3",),
    "rpe": ("mrnc-eval rpe sample_logs/loop_forest.gt.tum results/latest/trajectory.tum --delta 1 --delta-unit m",),
    "table": ("mrnc-eval table results/ --out table1.md",),
    "report": ("mrnc-eval report results/latest --pdf",),
    "nightly": ("mrnc-eval nightly sample_logs --out nightly_reports --jobs 2",),
    "compare": ("mrnc-eval compare results/run-a results/run-b --changed-only",
                "mrnc-eval compare --history nightly_reports --nights 2026-11-20 2026-11-21"),
    "export": ("mrnc-eval export results/latest --mcap run.mcap",),
    "simulate": ("mrnc-eval simulate sim/yard.bag --scene yard --path circle --duration 20",),
}

# Formats a verb reads, shown under its examples (lines keep their relative indentation; no [ ]: rich markup).
FORMATS: dict[str, str] = {
    "table": "Manifest (YAML; paths relative to it):\n\n"
             "  sequences:\n"
             "    forest:\n"
             "      reference: forest.gt.tum      # or forest.mcap:/ground_truth: what ape reads\n"
             "      methods:\n"
             "        lio: results/forest-lio/    # a slam result folder (slam.table_trajectory picks the file)\n"
             "        kiss-icp: kiss/forest.tum  # a TUM, KITTI or EuRoC file\n"
             "        odometry: forest.mcap:/odom  # a log's pose topic\n"
             "        orb: null                  # no trajectory: Failed",
}

GLOBAL_FLAGS = ("--debug", "--quiet", "-q", "--verbose")  # plus -v, -vv, ...: accepted before or after the verb
_BOOL_WORDS = {"true", "false", "yes", "no", "on", "off", "1", "0"}


def _is_global(token: str) -> bool:
    return token in GLOBAL_FLAGS or (len(token) > 1 and token[0] == "-" and set(token[1:]) == {"v"})


_PLAIN_TYPES = {"path": "PATH", "file": "PATH", "directory": "PATH", "int": "INT", "float": "NUMBER", "str": "TEXT"}


class PlainArgument(TyperArgument):
    """An argument shown by its metavar alone (`LOG...`), not `{LOG...}...` and `<list[Path]>`."""

    def display_type_rich(self, ctx: click.Context) -> str | None:
        return None

    def _rich_display_name(self) -> str:
        return self._usage_display_name()

    def _usage_display_name(self) -> str:
        name = self.metavar or str(self.name).upper()
        if self.nargs != 1 and not name.endswith("...") and " " not in name:  # "RUN_A RUN_B" counts itself
            name += "..."
        return name if self.required or name.startswith("[") else f"[{name}]"


class PlainOption(TyperOption):
    """A flag shows no value; a choice lists its choices; anything else a plain word (PATH, NUMBER)."""

    def display_type_rich(self, ctx: click.Context) -> str | None:
        if self.is_flag or self.count:
            return None
        if self.metavar is not None:
            return self.metavar
        label = (super().display_type(ctx) or "").strip("<>")  # "<path>", "<list[str]>", "<lio|kiss-icp>"
        if "|" in label:  # spaces around |: a narrow terminal wraps between choices, never inside one
            choices = label.removeprefix("list[").removesuffix("]") if label.startswith("list[") else label
            return "[" + " | ".join(choices.split("|")) + "]"
        words = label.removeprefix("list[").removesuffix("]").split(",")  # a tuple option: one word per value
        return " ".join(_PLAIN_TYPES.get(w.strip(), "TEXT") for w in words)


def _flag_value_mistake(command: click.Command, args: list[str]) -> str | None:
    """`--no-loop true LOG`: a flag followed by a truth word that is not a file is a mistake
    (the word would silently become an input); the message says how to write it."""
    flags = {opt for p in command.params if isinstance(p, TyperOption) and (p.is_flag or p.count)
             for opt in (*p.opts, *p.secondary_opts)}
    for flag, value in itertools.pairwise(args):
        if flag == "--":
            return None
        if flag in flags and value.lower() in _BOOL_WORDS and not Path(value).exists():
            return f"{flag} is a flag and takes no value: write {flag} alone (drop {value!r})"
    return None


def _plain_params(params: list[Any]) -> list[Any]:
    for param in params:
        if type(param) is TyperOption:
            param.__class__ = PlainOption
        elif type(param) is TyperArgument:
            param.__class__ = PlainArgument
    return params


class PlainGroup(TyperGroup):
    """The verb group: plain help for every verb, examples as epilogs, global options anywhere."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        for name, command in self.commands.items():
            if isinstance(command, TyperCommand) and type(command) is TyperCommand:
                command.__class__ = PlainCommand
            _plain_params(command.params)
            if command.help:  # rich markup keeps single newlines: the docstring's wrapping would show
                command.help = re.sub(r"(?<!\n)\n(?!\n)", " ", inspect.cleandoc(command.help))
            if name in EXAMPLES and not command.epilog:
                command.epilog = "Example" + ("s" if len(EXAMPLES[name]) > 1 else "") + ":\n\n" + \
                    "\n\n".join(f"  {e}" for e in EXAMPLES[name]) + (f"\n\n{FORMATS[name]}" if name in FORMATS else "")

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        return super().parse_args(ctx, hoist_global_options(args))

    def get_params(self, ctx: click.Context) -> list[Any]:
        return _plain_params(super().get_params(ctx))


class PlainCommand(TyperCommand):
    def get_params(self, ctx: click.Context) -> list[Any]:  # --help is added here, as a plain option
        return _plain_params(super().get_params(ctx))

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        mistake = _flag_value_mistake(self, args)
        if mistake:
            raise UsageError(mistake, ctx)
        return super().parse_args(ctx, args)


def hoist_global_options(args: list[str]) -> list[str]:
    """Move --debug, -v, -q written after the verb to before it (`slam LOG --debug`); nothing
    after `--` moves."""
    end = args.index("--") if "--" in args else len(args)
    verb = next((i for i, a in enumerate(args[:end]) if not a.startswith("-")), None)
    if verb is None:
        return list(args)
    moved = [a for a in args[verb:end] if _is_global(a)]
    kept = [a for a in args[verb:end] if not _is_global(a)]
    return [*args[:verb], *moved, *kept, *args[end:]]
