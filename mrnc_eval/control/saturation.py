"""The paper's safety saturation. Its lambda / lambda-bar construction is exactly a clamp
(paper-notes 4.1; the printed lambda-bar has a typo, "|U + 1" for "|U| + 1")."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def clamp(u: NDArray[np.float64] | float, u_min: float, u_max: float) -> NDArray[np.float64]:
    return np.clip(u, u_min, u_max)


def lambda_construction(u: NDArray[np.float64], u_min: float, u_max: float) -> NDArray[np.float64]:
    """U* = lambda U + lambda_bar as printed (with the typo fixed); equals clamp(U)."""
    u = np.asarray(u, dtype=float)
    outside = (u >= u_max) | (u <= u_min)
    lam = np.where(outside, 1.0 / (np.abs(u) + 1.0), 1.0)
    lam_bar = np.where(u >= u_max, u_max - u / (np.abs(u) + 1.0),
                       np.where(u <= u_min, u_min - u / (np.abs(u) + 1.0), 0.0))
    return lam * u + lam_bar
