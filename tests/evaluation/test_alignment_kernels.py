"""geometry/_kernels.c (APE's alignment sums and aligned distances in one pass) gives the bits of
the numpy code it replaces, on any memory layout, for every alignment mode; built here from this
tree's source (an installed build may be older)."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from mrnc_eval.data import Trajectory
from mrnc_eval.evaluation import ape
from mrnc_eval.geometry import point_fit as align
from tests.c_build import build_extension

SOURCE = Path(align.__file__).with_name("_kernels.c")


@pytest.fixture(scope="module")
def kernels(tmp_path_factory: pytest.TempPathFactory) -> ModuleType:
    # -O3 -march=native: FMA is available to the compiler, so the no-contraction pragma is tested too
    return build_extension(SOURCE, "mrnc_eval.geometry._kernels", tmp_path_factory.mktemp("kernels"),
                           ("-O3", "-march=native"))


def _layouts(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    base = rng.normal(scale=50.0, size=(n, 3)) + rng.uniform(-1e3, 1e3, size=3)
    cols = np.ascontiguousarray(base.T)  # (3, n): as the TUM reader hands positions out
    wide = np.zeros((n, 8))
    wide[:, 2:5] = base
    return [base, cols.T, wide[:, 2:5], base[::-1]]


@pytest.mark.parametrize("n", [3, 1000, 3 * align.CHUNK + 17])
def test_alignment_sums_match_numpy_bits(kernels: ModuleType, monkeypatch: pytest.MonkeyPatch, n: int) -> None:
    rng = np.random.default_rng(n)
    for x in _layouts(rng, n):
        y = x @ np.linalg.qr(rng.normal(size=(3, 3)))[0].T + rng.normal(scale=0.1, size=(n, 3)) + 5.0
        for with_scale in (False, True):
            monkeypatch.setattr(align, "_kernels", None)
            slow = align.umeyama(x, y, with_scale)
            monkeypatch.setattr(align, "_kernels", kernels)
            fast = align.umeyama(x, y, with_scale)
            for a, b in zip(fast, slow, strict=True):
                assert np.asarray(a).tobytes() == np.asarray(b).tobytes()
        mx = align._sequential_sum(x) / n
        assert np.array(kernels.column_sums(x)).tobytes() == align._sequential_sum(x).tobytes()
        outer = np.array(kernels.centred_outer_sum(y, tuple(mx), x, tuple(mx))).reshape(3, 3)
        assert outer.tobytes() == align._sequential_outer_sum(y, mx, x, mx).tobytes()


@pytest.mark.parametrize("mode", ["se3", "sim3", "scale", "yaw", "origin"])
def test_aligned_distances_match_numpy_bits(kernels: ModuleType, monkeypatch: pytest.MonkeyPatch, mode: str) -> None:
    rng = np.random.default_rng(7)
    n = 2 * ape.ANGLE_BLOCK + 5
    for p, q in zip(_layouts(rng, n), _layouts(rng, n), strict=True):
        quat = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
        ref = Trajectory(np.arange(n, dtype=float), q, quat, name="ref")
        est = Trajectory(np.arange(n, dtype=float), p * 1.01 + 2.0, quat, name="est")
        monkeypatch.setattr(ape, "_kernels", None)
        slow = ape.aligned_distances(ape.aligned_pair(ref, est, mode, None, None))
        monkeypatch.setattr(ape, "_kernels", kernels)
        fast = ape.aligned_distances(ape.aligned_pair(ref, est, mode, None, None))
        assert fast.tobytes() == slow.tobytes()


def test_kernels_refuse_wrong_shapes(kernels: ModuleType) -> None:
    with pytest.raises(ValueError, match=r"\(n, 3\) float64"):
        kernels.column_sums(np.zeros((4, 2)))
    with pytest.raises(ValueError, match=r"\(n, 3\) float64"):
        kernels.column_sums(np.zeros((4, 3), dtype=np.float32))
    with pytest.raises(ValueError, match="differ in length"):
        kernels.centred_outer_sum(np.zeros((4, 3)), (0.0, 0.0, 0.0), np.zeros((5, 3)), (0.0, 0.0, 0.0))
