"""`mrnc-eval simulate`: synthetic recordings with ground truth, with a progress bar."""

from __future__ import annotations

import sys
from pathlib import Path

from mrnc_eval.config import Config
from mrnc_eval.errors import UsageError


def main(out: Path, cfg: Config, *, scene: str, path: str, duration: float | None, lidar: str, columns: int,
         rate: float, fmt: str, seed: int) -> None:
    from mrnc_eval.sim.recorder import LIDAR_MODELS, SimRequest, simulate_log
    from mrnc_eval.sim.scene import SCENES

    if fmt not in ("mcap", "db3", "bag"):
        raise UsageError(f"--format {fmt!r}: mcap, db3 or bag")
    if scene not in SCENES:
        raise UsageError(f"--scene {scene!r}: choose from {', '.join(SCENES)}")
    if path not in ("circle", "figure8", "loop", "line"):
        raise UsageError(f"--path {path!r}: circle, figure8, loop or line")
    if lidar not in LIDAR_MODELS or columns not in (512, 1024, 2048) or rate not in (10.0, 20.0):
        raise UsageError(f"--lidar {lidar} --columns {columns} --rate {rate:g}: OS0 models are "
                         f"{', '.join(LIDAR_MODELS)} with 512/1024/2048 columns at 10 or 20 Hz")
    req = SimRequest(scene=scene, path=path, duration_s=duration, lidar=lidar, columns=columns, rate_hz=rate,
                     fmt=fmt, seed=seed)
    if sys.stderr.isatty():
        from rich.progress import Progress

        with Progress(transient=True) as bar:
            task = bar.add_task("simulating sweeps", total=None)
            written = simulate_log(out, cfg, req, lambda n, total: bar.update(task, completed=n, total=total))
    else:
        written = simulate_log(out, cfg, req)
    sys.stderr.write(f"wrote {written}\n")
