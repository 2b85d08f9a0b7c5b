"""The cyclic garbage collector paused while a `slam` run starts up.

Why: a short run creates ~70,000 long-lived container objects while it imports its ~500 modules, reads its
configuration and opens the log (the classes, functions and constants of numpy, gtsam, rosbags
and the package), and the collector walks them again on each older-generation pass: ~40 ms CPU
of a 0.7 s run (forest30 --end 0.25: 15 collections of generation 1 or 2, one full one 15 ms),
nearly none of it finding garbage. Paused from the command's start (`python -m mrnc_eval`: from
before the CLI's imports, resumed at once for any other command) to the SLAM loop's; then what
exists is frozen (gc.freeze: moved to the permanent generation, never walked again; without it
the first pass after resuming walks everything made while paused, ~90 ms) and collection resumes,
so a long run frees its cyclic garbage as before. The cost: cyclic garbage already made when the
run starts is never freed (a process running many commands in turn, as the tests do, keeps
what was garbage at each start). Only ever re-enables what `pause` disabled (a caller that
turned collection off keeps it off).
"""

from __future__ import annotations

import gc

_state = {"paused": False}


def pause() -> None:
    """Stop automatic collection until `resume` (a no-op when it is already off)."""
    if gc.isenabled():
        gc.disable()
        _state["paused"] = True


def resume() -> None:
    """Everything made so far frozen and automatic collection back on, if `pause` turned it off
    (idempotent)."""
    if _state["paused"]:
        _state["paused"] = False
        gc.freeze()
        gc.enable()
