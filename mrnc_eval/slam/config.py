"""SLAM parameters. Defaults follow LIO-SAM's params.yaml (see shared/docs/lio-sam-reference.md)."""

from __future__ import annotations

from dataclasses import dataclass

from mrnc_eval.params import param


@dataclass(frozen=True)
class SlamConfig:
    method: str = param("lio", "SLAM method: lio (this project's LIO-SAM replay) or kiss-icp (peer)")
    use_loop_closure: bool = param(True, "enable radius-search loop closure")
    use_gps: bool = param(True, "add GNSS factors when the log has GNSS")
