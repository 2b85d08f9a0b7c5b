"""`mrnc-eval simulate`: synthetic recordings with ground truth, with a progress bar over sweeps
when stderr is a terminal."""

from __future__ import annotations

import sys
from pathlib import Path

from mrnc_eval.config import Config
from mrnc_eval.errors import UsageError


def main(out: Path, cfg: Config, *, scene: str, path: str, duration: float | None, lidar: str, columns: int,
         rate: float, fmt: str, seed: int | None, profile: str | None = None) -> None:
    from mrnc_eval.commands.progress import progress_bar
    from mrnc_eval.sim.recorder import SimRequest, simulate_log, validate

    req = SimRequest(scene=scene, path=path, duration_s=duration, lidar=lidar, columns=columns, rate_hz=rate,
                     fmt=fmt, seed=seed, profile=profile)
    try:
        validate(req)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    with progress_bar(total=1) as bar:  # the sweep count is known once the mission has been driven
        if bar is None:
            written = simulate_log(out, cfg, req)
        else:
            task = bar.add_task(f"simulating {req.lidar} sweeps ({req.profile or cfg.sim.profile} profile)", total=None)
            written = simulate_log(out, cfg, req, lambda n, total: bar.update(task, completed=n, total=total))
    sys.stderr.write(f"wrote {written}\n")
