"""evo's spellings on `ape` and `rpe`, so an evo script runs with `evo_ape` replaced by `mrnc-eval ape`.

Options that differ from ours only in name (`--t_max_diff`, `--t_offset`, `--n_to_align`,
`-r/--pose_relation`, `--project_to_plane`, `--save_results`, `--plot_mode`, `--save_plot`, `-d`,
`-u`, `--all_pairs`, `--pairs_from_reference`, `--sync_method`) are declared as second names of
our options in cli.py. This module rewrites the few that cannot be: evo's alignment switches
(`-a/--align`, `-s/--correct_scale`, `--align_origin`, and the combined `-as`) become one
`--align MODE`, and evo's bare `-p/--plot` (open a window) is dropped with a note, since this
tool writes plots to files. Nothing after `--` is touched.
"""

from __future__ import annotations

import sys
from pathlib import Path

from mrnc_eval.errors import UsageError

VERBS = ("ape", "rpe")
ALIGN_MODES = ("se3", "sim3", "scale", "origin", "yaw", "none")  # evaluation.modes.AlignMode, import-light copy
# Which of evo's switches mean what (evo's main_ape/main_rpe): -a SE(3), -a -s Sim(3), -s alone scale only.
_ALIGN_FLAGS = {"-a": "a", "--align": "a", "-s": "s", "--correct_scale": "s", "-as": "as", "-sa": "as",
                "--align_origin": "o"}
_PLOT_FLAGS = ("-p", "--plot")


def _verb_index(args: list[str]) -> int | None:
    for i, a in enumerate(args):
        if a == "--":
            return None
        if not a.startswith("-"):
            return i
    return None


def _mode(flags: set[str]) -> str:
    if "o" in flags and flags & {"a", "s"}:
        raise UsageError("--align_origin cannot be combined with -a or -s (evo refuses it too)")
    if "o" in flags:
        return "origin"
    if {"a", "s"} <= flags:
        return "sim3"
    return "se3" if "a" in flags else "scale"


def _takes_plot_file(args: list[str], i: int) -> bool:
    """`--plot FILE` (ours) versus evo's bare `-p/--plot`: a following word is the plot file unless
    it is an option or an existing input without a plot suffix (`--plot gt.tum est.tum`)."""
    nxt = args[i + 1] if i + 1 < len(args) else "-"
    if nxt.startswith("-") or nxt == "--":
        return False
    return nxt.lower().endswith((".svg", ".png", ".pdf")) or not Path(nxt).exists()


def translate(args: list[str]) -> list[str]:
    """`args` with evo's alignment switches and bare plot flags of ape/rpe rewritten (see the
    module docstring); any other verb's arguments are returned unchanged."""
    verb = _verb_index(args)
    if verb is None or args[verb] not in VERBS:
        return list(args)
    end = args.index("--") if "--" in args else len(args)
    out: list[str] = list(args[:verb + 1])
    flags: set[str] = set()
    explicit: str | None = None
    i = verb + 1
    while i < end:
        a = args[i]
        if a in ("--align", "-a") and i + 1 < end and args[i + 1] in ALIGN_MODES:
            explicit = args[i + 1]  # ours: --align MODE
            i += 2
            continue
        if a.startswith("--align="):
            explicit = a.split("=", 1)[1]
            i += 1
            continue
        if a in _ALIGN_FLAGS:
            flags.update(_ALIGN_FLAGS[a].replace("as", "a s").split())
        elif a in _PLOT_FLAGS and _takes_plot_file(args, i):
            out += ["--plot", args[i + 1]]
            i += 1
        elif a in _PLOT_FLAGS:
            sys.stderr.write(f"note: {a} (evo: show the plot in a window) ignored; mrnc-eval writes plots to files: "
                             "--save_plot FILE or --plot FILE (.svg, .png, .pdf)\n")
        else:
            out.append(a)
        i += 1
    if flags:
        mode = _mode(flags)
        if explicit is not None and explicit != mode:
            raise UsageError(f"--align {explicit} and evo's alignment switches (giving {mode}) disagree; use one")
        explicit = mode
    if explicit is not None:
        out += ["--align", explicit]
    return out + list(args[end:])
