"""`mrnc-eval simulate`: synthetic recordings with ground truth, with a progress bar over sweeps
when stderr is a terminal."""

from __future__ import annotations

import sys
from pathlib import Path

from mrnc_eval.config import Config
from mrnc_eval.errors import OutputError, UsageError

SIM_OUTPUT_BYTES = 100_000_000  # free space asked for before simulating (a minute of OS0-128 is ~50 MB)
_BAG_FILES = (".mcap", ".db3", ".yaml")  # what a ROS 2 bag folder written by this tool holds


def check_target(out: Path, *, force: bool) -> None:
    """Before any work: never replace what the user did not ask to replace. An existing target
    is refused unless --force, and --force replaces only a log this tool wrote (the simulator
    writes `<name>.gt.tum` beside every log; a recording, or a folder of anything else, has none)."""
    from mrnc_eval.io.ground_truth import gt_tum_path
    from mrnc_eval.results import check_output_root

    if out.name in ("", ".", ".."):
        raise UsageError(f"{out}: give the log a file or folder name, e.g. {out / 'sim.mcap'}")
    check_output_root(out.parent if str(out.parent) else Path("."), need_bytes=SIM_OUTPUT_BYTES)
    if not out.exists() and not out.is_symlink():
        return
    if out.is_dir() and not out.is_symlink() and not any(out.iterdir()):
        return  # an empty folder: nothing to lose
    ours = gt_tum_path(out).is_file() and (
        out.is_file() or (out.is_dir() and all(p.is_file() and p.suffix in _BAG_FILES for p in out.iterdir())))
    if not force:
        raise OutputError(out, "already exists; not replaced (--force replaces a log this tool wrote)")
    if not ours:
        raise OutputError(out, "exists and is not a log this tool wrote (no .gt.tum beside it, or other files "
                          "inside); not replaced, even with --force")


def main(out: Path, cfg: Config, *, scene: str, path: str, duration: float | None, lidar: str, columns: int,
         rate: float, fmt: str, seed: int | None, profile: str | None = None,
         force: bool = False) -> None:
    from mrnc_eval.commands.progress import progress_bar
    from mrnc_eval.sim.recorder import SimRequest, simulate_log, validate

    req = SimRequest(scene=scene, path=path, duration_s=duration, lidar=lidar, columns=columns, rate_hz=rate,
                     fmt=fmt, seed=seed, profile=profile)
    try:
        validate(req)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    check_target(out, force=force)
    with progress_bar(total=1) as bar:  # the sweep count is known once the mission has been driven
        if bar is None:
            written = simulate_log(out, cfg, req)
        else:
            task = bar.add_task(f"simulating {req.lidar} sweeps ({req.profile or cfg.sim.profile} profile)", total=None)
            written = simulate_log(out, cfg, req, lambda n, total: bar.update(task, completed=n, total=total))
    sys.stderr.write(f"wrote {written}\n")
