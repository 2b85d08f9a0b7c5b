"""Error statistics, with evo's definitions (population std, sse = sum of squares)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

STAT_KEYS = ("rmse", "mean", "median", "std", "min", "max", "sse")


def error_stats(errors: NDArray[np.float64]) -> dict[str, float]:
    e = np.asarray(errors, dtype=float)
    sq = float(np.dot(e, e))
    return {
        "rmse": float(np.sqrt(sq / e.size)),
        "mean": float(np.mean(e)),
        "median": float(np.median(e)),
        "std": float(np.std(e)),
        "min": float(np.min(e)),
        "max": float(np.max(e)),
        "sse": sq,
    }
