"""APE split the way a ground-robot team reads it (`ape --decompose`).

For each matched pose, the aligned estimate's position error e = p - q is expressed along
the reference's direction of travel (horizontal tangent t of the reference path), across it
(n = z x t: positive to the left, REP-103) and vertically (z); the yaw error is the
estimate's heading minus the reference's (static-xyz yaw, wrapped to [-180, 180) deg).
All four are signed: their mean is a bias (e.g. a lateral offset), their rmse the spread
around zero. Statistics as for APE (evo's definitions).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.errors import EvaluationError
from mrnc_eval.evaluation.stats import error_stats
from mrnc_eval.geometry import lie

MIN_STEP_M = 1e-6  # reference steps shorter than this do not define a direction


@dataclass(frozen=True)
class Decomposition:
    """Position errors split along the path, across it and vertically, m."""

    along_m: NDArray[np.float64]
    cross_m: NDArray[np.float64]
    vertical_m: NDArray[np.float64]
    yaw_deg: NDArray[np.float64]

    def summary(self) -> dict[str, dict[str, float]]:
        return {"along_m": error_stats(self.along_m), "cross_m": error_stats(self.cross_m),
                "vertical_m": error_stats(self.vertical_m), "yaw_deg": error_stats(self.yaw_deg)}


def travel_directions(ref_xyz: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N, 2) unit horizontal tangents of a path (central differences; where the path stands
    still, the nearest defined direction before it, else after it)."""
    xy = ref_xyz[:, :2]
    d = np.empty_like(xy)
    d[1:-1] = xy[2:] - xy[:-2]
    d[0], d[-1] = xy[1] - xy[0], xy[-1] - xy[-2]
    norm = np.linalg.norm(d, axis=1)
    ok = norm > MIN_STEP_M
    if not ok.any():
        raise EvaluationError("--decompose: the reference does not move in the horizontal plane, so along- and "
                              "cross-track are undefined")
    idx = np.where(ok, np.arange(ok.size), -1)
    idx = np.maximum.accumulate(idx)  # last defined direction at or before each pose
    first = int(np.flatnonzero(ok)[0])
    idx[idx < 0] = first
    tangent: NDArray[np.float64] = d[idx] / norm[idx, None]
    return tangent


def decompose(ref_xyz: NDArray[np.float64], est_xyz: NDArray[np.float64], ref_rot: NDArray[np.float64],
              est_rot: NDArray[np.float64]) -> Decomposition:
    """Signed along-track, cross-track, vertical (m) and yaw (deg) errors of matched, aligned poses."""
    t = travel_directions(ref_xyz)
    e = est_xyz - ref_xyz
    along = e[:, 0] * t[:, 0] + e[:, 1] * t[:, 1]
    cross = -e[:, 0] * t[:, 1] + e[:, 1] * t[:, 0]  # component along z x t
    yaw_e, _, _ = lie.yaw_pitch_roll_sxyz(est_rot)
    yaw_r, _, _ = lie.yaw_pitch_roll_sxyz(ref_rot)
    yaw = np.degrees((yaw_e - yaw_r + np.pi) % (2 * np.pi) - np.pi)
    return Decomposition(along, cross, e[:, 2].copy(), yaw)
