"""`mrnc-eval simulate`: synthetic recordings with ground truth, with a progress bar over sweeps
when stderr is a terminal."""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from mrnc_eval.config import Config
from mrnc_eval.errors import OutputError, UsageError
from mrnc_eval.io.containers import FORMAT_NAMES, FORMAT_SUFFIX, SUFFIX_FORMAT

if TYPE_CHECKING:
    from mrnc_eval.recording.recorder import SimRequest

log = logging.getLogger(__name__)

SIM_OUTPUT_BYTES = 100_000_000  # free space asked for before simulating (a minute of OS0-128 is ~50 MB)
_BAG_FILES = (".mcap", ".db3", ".yaml")  # what a ROS 2 bag folder written by this tool holds


def log_target(out: str | Path, fmt: str | None) -> tuple[Path, str]:
    """The log to write and its format, from OUT's suffix and --format: .bag a ROS 1 bag, .mcap a
    ROS 2 MCAP file, .db3 a ROS 2 sqlite3 file; a folder (OUT ends in / or is one) a ROS 2 bag folder
    (sqlite3 unless --format mcap); no suffix: --format's suffix (default mcap) is added. A suffix
    that names another format than --format, or any other suffix, is a UsageError."""
    text = str(out)
    path = Path(text)
    named = SUFFIX_FORMAT.get(path.suffix.lower())
    if named is not None:
        if fmt is not None and fmt != named:
            raise UsageError(f"{path}: the name makes a {FORMAT_NAMES[named]} but --format {fmt} asks for a "
                             f"{FORMAT_NAMES[fmt]}; drop --format or name it {path.with_suffix(FORMAT_SUFFIX[fmt])}")
        return path, named
    if text.endswith(("/", os.sep)) or path.is_dir():
        if fmt == "bag":
            raise UsageError(f"{text}: a ROS 1 bag is one file, not a folder; name it {path.name or 'sim'}.bag")
        return path, fmt or "db3"
    if path.suffix:
        raise UsageError(f"{path}: unknown log suffix {path.suffix!r}; use .bag (ROS 1 bag), .mcap (ROS 2 MCAP) "
                         "or .db3 (ROS 2 sqlite3), or end OUT with / for a ROS 2 bag folder")
    fmt = fmt or "mcap"
    return path.with_name(path.name + FORMAT_SUFFIX[fmt]), fmt


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


def main(out: str | Path, cfg: Config, *, scene: str, path: str, duration: float | None, lidar: str, columns: int,
         rate: float, fmt: str | None, seed: int | None, profile: str | None = None,
         force: bool = False) -> None:
    """The `simulate` verb: the format from OUT's name and --format (log_target), checked before
    any work; the log and its ground truth written atomically."""
    from mrnc_eval.commands.progress import progress_bar
    from mrnc_eval.recording.recorder import SimRequest, check_lidar_sets, simulate_log, validate

    target, log_format = log_target(out, fmt)
    req = SimRequest(scene=scene, path=path, duration_s=duration, lidar=lidar, columns=columns, rate_hz=rate,
                     fmt=log_format, seed=seed, profile=profile)
    validate(req)  # a UsageError naming every unsupported choice, before any work
    check_lidar_sets(cfg, req)
    check_target(target, force=force)
    with progress_bar(total=1) as bar:  # the sweep count is known once the mission has been driven
        if bar is None:
            written = simulate_log(target, cfg, req)
        else:
            task = bar.add_task(f"simulating {req.lidar} sweeps ({req.profile or cfg.sim.profile} profile)", total=None)
            written = simulate_log(target, cfg, req, lambda n, total: bar.update(task, completed=n, total=total))
    sys.stderr.write(wrote_line(Path(written), req, cfg) + "\n")
    for line in drive_warnings(Path(written)):
        log.warning("%s", line)


def drive_warnings(written: Path) -> list[str]:
    """The simulated drive's safety stops (from <log>.errors.json): the log then shows a machine that
    stops mid-path, which a user who asked for the path should hear about."""
    import json

    from mrnc_eval.recording.recorder import errors_json_path

    f = errors_json_path(written)
    drive = json.loads(f.read_text(encoding="utf-8")).get("drive", {}) if f.is_file() else {}
    return [f"{written.name}: the simulated machine stopped at {e['t_s']:.1f} s ({e['message']}): RAID's safety "
            f"constraint; the log stands still from there. {_STOP_HINT.get(e.get('cause', ''), '')}".rstrip()
            for e in drive.get("safety_stops", [])]


# What makes each stop cause (control.controllers.STOP_CAUSES) happen, for the user who asked for the drive.
_STOP_HINT = {
    "barrier_at_clamp": "The command sat at control.actuator.u_max_rpm: a speed beyond what it allows "
                        "(control.pure_pursuit.desired_speed_mps) does this",
    "barrier": "The side's speed error outgrew the funnel below the clamp: a speed or a turn the drive cannot "
               "follow does this (in a turn the outer side runs faster than control.pure_pursuit.desired_speed_mps)",
}


def _size_text(path: Path) -> str:
    size = sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) if path.is_dir() else path.stat().st_size
    return f"{size / 1e6:.1f} MB" if size >= 1e5 else f"{size / 1e3:.0f} kB"


def wrote_line(written: Path, req: SimRequest, cfg: Config) -> str:
    """What was written: the log (format, size, duration, what it holds) and its ground truth."""
    from mrnc_eval.io.ground_truth import gt_tum_path

    gt = gt_tum_path(written)
    duration = ""
    if gt.is_file():
        lines = [ln.split() for ln in gt.read_text(encoding="utf-8").splitlines() if ln and not ln.startswith("#")]
        if len(lines) > 1:
            duration = f", {float(lines[-1][0]) - float(lines[0][0]):.1f} s"
    what = (f"{req.scene} {req.path}, {req.lidar} x {req.columns} at {req.rate_hz:g} Hz, "
            f"{req.profile or cfg.sim.profile} profile, seed {cfg.sim.seed if req.seed is None else req.seed}")
    line = f"wrote {written} ({FORMAT_NAMES[req.fmt]}, {_size_text(written)}{duration}: {what})"
    return line + (f" and its ground truth {gt} (TUM; slam and table find it beside the log)" if gt.is_file() else "")
