"""The cyclic garbage collector paused while a `slam` run starts up.

Why: a short run creates ~70,000 long-lived container objects while it imports its ~500 modules, reads its
configuration and opens the log (the classes, functions and constants of numpy, gtsam, rosbags
and the package), and the collector walks them again on each older-generation pass: ~40 ms CPU
of a 0.7 s run (forest30 --end 0.25: 15 collections of generation 1 or 2, one full one 15 ms),
nearly none of it finding garbage. Paused from the command's start (`python -m mrnc_eval`: from
before the CLI's imports, resumed at once for any other command) to the SLAM loop's; then what
exists is frozen (gc.freeze: moved to the permanent generation, never walked again; without it
the first pass after resuming walks everything made while paused, ~90 ms) and collection resumes,
so a long run frees its cyclic garbage as before. When the command ends (`end_command`, also on an
error) what was frozen is handed back to the collector (gc.unfreeze), unless the process exits
after this one command (`python -m mrnc_eval`): a process running many commands in turn (the
tests, a loop calling cli.main over many logs) would otherwise keep the cyclic garbage that existed
at each command's start for good. Only ever re-enables what `pause` disabled (a caller that
turned collection off keeps it off), and only unfreezes what it froze (nothing frozen before it).
"""

from __future__ import annotations

import gc

_state = {"paused": False, "froze": False, "one_command": False}


def pause(*, one_command: bool = False) -> None:
    """Stop automatic collection until `resume` (a no-op when it is already off); one_command:
    the process exits after this command (what `resume` freezes may stay frozen)."""
    _state["one_command"] = _state["one_command"] or one_command
    if gc.isenabled():
        gc.disable()
        _state["paused"] = True


def resume() -> None:
    """Everything made so far frozen and automatic collection back on, if `pause` turned it off
    (idempotent)."""
    if _state["paused"]:
        _state["paused"] = False
        _state["froze"] = gc.get_freeze_count() == 0  # someone else's frozen objects are never unfrozen here
        gc.freeze()
        gc.enable()


def end_command() -> None:
    """`resume`, then what it froze back in the collector's care, unless the process exits now."""
    resume()
    if _state["froze"] and not _state["one_command"]:
        _state["froze"] = False
        gc.unfreeze()
