"""slam.gps.use_elevation with the residual gate: said, not silently ignored (docs/simulation.md,
"holding the line's z")."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from mrnc_eval.data import GnssSeries
from mrnc_eval.slam.config import SlamConfig
from mrnc_eval.slam.replay import _Replay


def _fixes(n: int = 20) -> GnssSeries:
    return GnssSeries(np.arange(n) * 0.2, np.zeros((n, 3)), np.zeros((n, 3)),
                      np.tile(np.diag([4e-4, 4e-4, 1e-3]), (n, 1, 1)), np.zeros(3))


@pytest.mark.parametrize(("use_elevation", "gate", "warned"), [
    (True, "residual", True),  # the default gate keeps the chain's z: the setting would do nothing
    (False, "residual", False),  # negative control: not asked for
    (True, "lio_sam", False),  # negative control: LIO-SAM's gate uses the fixes' height
])
def test_gnss_height_with_the_residual_gate_is_a_warning(use_elevation: bool, gate: str, warned: bool) -> None:
    base = SlamConfig()
    cfg = replace(base, gps=replace(base.gps, use_elevation=use_elevation, gate=gate))
    replay = _Replay.start(None, cfg, None, _fixes(), None, False)
    said = [w for w in replay.warnings if "use_elevation" in w]
    assert len(said) == int(warned)
