"""Index pairs for relative errors (evo filters semantics), vectorised or compiled."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.errors import EvaluationError

IndexPairs = tuple[NDArray[np.int64], NDArray[np.int64]]  # (first, second) pose indices


def pairs_by_frames(n: int, delta: int, all_pairs: bool) -> IndexPairs:
    if delta < 1:
        raise EvaluationError(f"delta in frames must be >= 1, got {delta}")
    if all_pairs:
        i = np.arange(0, n - delta)
        return i, i + delta
    ids = np.arange(0, n, delta)
    return ids[:-1], ids[1:]


def _pairs_by_distance_incremental(positions: NDArray[np.float64], delta: float) -> IndexPairs:
    # Sequential by nature (the accumulator resets at each pair, overshoot discarded);
    # compiled with numba when installed (the control and sim extras), else the same loop in Python: both add
    # step by step in float64, so the pairs are the same bits as evo's (a 1e6-pose walk: ~0.3 s in Python).
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    try:
        from numba import njit
    except ImportError:
        return _walk_python(steps, float(delta))

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

    first, second = walk(steps, float(delta))
    return first, second


def _walk_python(steps: NDArray[np.float64], delta: float) -> IndexPairs:
    """The same walk without numba (Python floats are IEEE doubles: the same sums, the same pairs)."""
    first: list[int] = []
    second: list[int] = []
    last, acc = 0, 0.0
    for i, step in enumerate(steps.tolist(), start=1):
        acc += step
        if acc >= delta:
            first.append(last)
            second.append(i)
            last, acc = i, 0.0
    return np.array(first, dtype=np.int64), np.array(second, dtype=np.int64)


def pairs_by_distance(positions: NDArray[np.float64], delta: float, all_pairs: bool, tol: float = 0.1) -> IndexPairs:
    if delta <= 0:
        raise EvaluationError(f"delta in metres must be > 0, got {delta}")
    if not all_pairs:
        return _pairs_by_distance_incremental(positions, delta)
    # evo: per i, the first j > i minimising |(D_j - D_i) - delta|, kept if <= delta * tol.
    # That error is unimodal in j (D is non-decreasing and rounding is monotone), so the
    # minimum lies at the start of one of the few distinct D values around the crossing;
    # runs of equal D (standing still) collapse to their first index, as evo's argmin does.
    d = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(positions, axis=0), axis=1))])
    n = d.size
    i = np.arange(n - 1)
    k = np.minimum(np.searchsorted(d, d[i] + delta, side="left"), n - 1)
    def run_start(j: NDArray[np.int64]) -> NDArray[np.int64]:
        return np.searchsorted(d, d[j], side="left")
    before = run_start(np.maximum(k - 1, 0))
    cands = np.stack([run_start(np.maximum(before - 1, 0)), before, run_start(k),
                      np.searchsorted(d, d[k], side="right")], axis=1)
    cands = np.clip(np.maximum(cands, (i + 1)[:, None]), 0, n - 1)
    err = np.abs((d[cands] - d[i][:, None]) - delta)
    # columns are in index order, so argmin's first minimum is the earliest j, as in evo
    best = np.argmin(err, axis=1)[:, None]
    j = np.take_along_axis(cands, best, axis=1)[:, 0]
    keep = np.take_along_axis(err, best, axis=1)[:, 0] <= delta * tol
    return i[keep], j[keep]
