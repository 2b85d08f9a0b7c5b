"""Index pairs for relative errors (evo filters semantics), vectorised or compiled."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.errors import EvaluationError


def pairs_by_frames(n: int, delta: int, all_pairs: bool) -> tuple[NDArray, NDArray]:
    if delta < 1:
        raise EvaluationError(f"delta in frames must be >= 1, got {delta}")
    if all_pairs:
        i = np.arange(0, n - delta)
        return i, i + delta
    ids = np.arange(0, n, delta)
    return ids[:-1], ids[1:]


def _pairs_by_distance_incremental(positions: NDArray, delta: float) -> tuple[NDArray, NDArray]:
    # Sequential by nature (the accumulator resets at each pair, overshoot discarded);
    # compiled with numba so float summation order equals evo's step-by-step sum.
    from numba import njit

    @njit(cache=True)
    def walk(steps: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
        first = np.empty(steps.size, np.int64)
        second = np.empty(steps.size, np.int64)
        k = 0
        last = 0
        acc = 0.0
        for i in range(1, steps.size + 1):
            acc += steps[i - 1]
            if acc >= delta:
                first[k] = last
                second[k] = i
                k += 1
                last = i
                acc = 0.0
        return first[:k], second[:k]

    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    return walk(steps, float(delta))


def pairs_by_distance(positions: NDArray, delta: float, all_pairs: bool, tol: float = 0.1) -> tuple[NDArray, NDArray]:
    if delta <= 0:
        raise EvaluationError(f"delta in metres must be > 0, got {delta}")
    if not all_pairs:
        return _pairs_by_distance_incremental(positions, delta)
    # per i: the first j > i minimising |D_j - D_i - delta|, kept if within delta * tol
    d = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(positions, axis=0), axis=1))])
    n = d.size
    i = np.arange(n - 1)
    target = d[i] + delta
    k = np.searchsorted(d, target, side="left")
    cand_lo = np.clip(k - 1, 0, n - 1)
    cand_hi = np.clip(k, 0, n - 1)
    cand_lo = np.maximum(cand_lo, i + 1)
    cand_hi = np.maximum(cand_hi, i + 1)
    err_lo = np.abs(d[cand_lo] - target)
    err_hi = np.abs(d[cand_hi] - target)
    j = np.where(err_hi < err_lo, cand_hi, cand_lo)  # ties: the earlier index
    keep = np.abs(d[j] - target) <= delta * tol
    return i[keep], j[keep]
