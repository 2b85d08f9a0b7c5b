"""slam/_match_kernels.c, scan-to-map matching's fits and rows: against numpy references (the plane
fit's arithmetic transcribed to numpy's element-wise operations gives the same bits; line and plane
fits against np.linalg.eigh), on degenerate neighbourhoods, and refusing arrays it would misread.
Built here from this tree's source with -O3 -march=native (FMA available to the compiler, so the
no-contraction pragma is tested too)."""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import sysconfig
import threading
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

import mrnc_eval.slam
from tests.needs import missing

SOURCE = Path(mrnc_eval.slam.__file__).with_name("_match_kernels.c")
REPO = Path(__file__).resolve().parents[2]
# the kernels' messages for a wrong shape, length or index, and numpy's for a wrong layout or a read-only output
REFUSED = "expected|differ|outside|must|contiguous|read-only"


@pytest.fixture(scope="module")
def kernels(tmp_path_factory: pytest.TempPathFactory) -> ModuleType:
    cc = (sysconfig.get_config_var("CC") or "cc").split()[0]
    include = sysconfig.get_paths()["include"]
    if shutil.which(cc) is None or not (Path(include) / "Python.h").exists():
        missing(f"cannot build {SOURCE.name}: no C compiler ({cc}) or no Python.h in {include}")
    out = tmp_path_factory.mktemp("match_kernels") / ("_match_kernels" + sysconfig.get_config_var("EXT_SUFFIX"))
    subprocess.run([cc, "-O3", "-march=native", "-shared", "-fPIC", f"-I{include}", str(SOURCE), "-o", str(out)],
                   check=True)
    spec = importlib.util.spec_from_file_location("mrnc_eval.slam._match_kernels", out)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _neighbourhoods(rng: np.random.Generator, n: int, shape: str) -> np.ndarray:
    """(n, 5, 3) neighbourhoods 5-40 m from the origin: "plane" (2 cm noise off a random plane),
    "line" (3 cm noise about a random line), "blob" (isotropic), "exact_plane" (no noise)."""
    centre = rng.normal(size=(n, 1, 3)) * 20.0
    basis = np.linalg.qr(rng.normal(size=(n, 3, 3)))[0]
    local = rng.normal(size=(n, 5, 3)) * {"plane": [0.3, 0.3, 0.02], "line": [0.4, 0.03, 0.03],
                                         "blob": [0.2, 0.2, 0.2], "exact_plane": [0.3, 0.3, 0.0]}[shape]
    return np.asarray(centre + np.einsum("nkj,nij->nki", local, basis), np.float64)


def _as_map(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The neighbourhoods as a map cloud (5n, 3), their indices (n, 5) and distances (all matched)."""
    n = len(points)
    return points.reshape(-1, 3).copy(), np.arange(5 * n, dtype=np.int64).reshape(n, 5), np.zeros((n, 5))


def _planes_same_ops(cloud: np.ndarray, idx: np.ndarray, max_offset: float, min_spread: float) -> np.ndarray:
    """fit_planes' arithmetic, operation by operation, in numpy (element-wise: no FMA, IEEE rounding)."""
    p = cloud[idx]
    n = len(idx)
    a00, a11, a22 = np.full(n, 1e-9), np.full(n, 1e-9), np.full(n, 1e-9)
    a01, a02, a12, b0, b1, b2 = (np.zeros(n) for _ in range(6))
    for k in range(5):
        x0, x1, x2 = p[:, k, 0], p[:, k, 1], p[:, k, 2]
        a00, a01, a02 = a00 + x0 * x0, a01 + x0 * x1, a02 + x0 * x2
        a11, a12, a22 = a11 + x1 * x1, a12 + x1 * x2, a22 + x2 * x2
        b0, b1, b2 = b0 - x0, b1 - x1, b2 - x2
    c00, c01, c02 = a11 * a22 - a12 * a12, a02 * a12 - a01 * a22, a01 * a12 - a02 * a11
    c11, c12, c22 = a00 * a22 - a02 * a02, a01 * a02 - a00 * a12, a00 * a11 - a01 * a01
    det = a00 * c00 + a01 * c01 + a02 * c02
    x0 = (c00 * b0 + c01 * b1 + c02 * b2) / det
    x1 = (c01 * b0 + c11 * b1 + c12 * b2) / det
    x2 = (c02 * b0 + c12 * b1 + c22 * b2) / det
    nrm = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    plane = np.stack([x0 / nrm, x1 / nrm, x2 / nrm, 1.0 / nrm], axis=1)
    off = np.abs(plane[:, None, 0] * p[..., 0] + plane[:, None, 1] * p[..., 1] + plane[:, None, 2] * p[..., 2]
                 + plane[:, None, 3])
    keep = (det != 0.0) & (nrm >= 1e-9) & ~(off > max_offset).any(axis=1)
    keep &= _in_plane_spread_same_ops(p, plane[:, :3]) >= min_spread * min_spread
    plane[~keep] = np.nan
    return plane


def _in_plane_spread_same_ops(p: np.ndarray, normal: np.ndarray) -> np.ndarray:
    n0, n1, n2 = normal.T
    small = np.abs(n2) < 0.9
    u0, u1, u2 = np.where(small, n1, 0.0), np.where(small, -n0, n2), np.where(small, 0.0, -n1)
    un = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    u0, u1, u2 = u0 / un, u1 / un, u2 / un
    v0, v1, v2 = n1 * u2 - n2 * u1, n2 * u0 - n0 * u2, n0 * u1 - n1 * u0
    c = np.zeros((len(p), 3))
    for k in range(5):
        c = c + p[:, k] / 5.0
    a = b = d = np.zeros(len(p))
    for k in range(5):
        x0, x1, x2 = (p[:, k] - c).T
        pu, pv = x0 * u0 + x1 * u1 + x2 * u2, x0 * v0 + x1 * v1 + x2 * v2
        a, b, d = a + pu * pu / 5.0, b + pu * pv / 5.0, d + pv * pv / 5.0
    return np.asarray(0.5 * (a + d) - np.sqrt(0.25 * ((a - d) * (a - d)) + b * b))


@pytest.mark.parametrize("shape", ["plane", "line", "blob", "exact_plane"])
def test_plane_fits_give_the_bits_of_their_arithmetic_in_numpy(kernels: ModuleType, shape: str) -> None:
    rng = np.random.default_rng(1)
    cloud, idx, dist = _as_map(_neighbourhoods(rng, 4000, shape))
    for max_offset, min_spread in ((0.2, 0.0), (0.05, 0.05), (1e9, 0.2)):
        planes = np.empty((len(idx), 4))
        kernels.fit_planes(cloud, idx, dist, 1.0, max_offset, min_spread, planes, None)
        with np.errstate(all="ignore"):
            expected = _planes_same_ops(cloud, idx, max_offset, min_spread)
        assert planes.tobytes() == expected.tobytes()
    kept = ~np.isnan(planes[:, 0])
    assert 0 < kept.sum() < len(idx) or shape in ("line", "blob")  # the last setting keeps some, drops some


def test_plane_fits_agree_with_eigh(kernels: ModuleType) -> None:
    """Noise-free planar neighbourhoods: the fitted normal is the covariance's smallest eigenvector
    and the points lie on the plane (to the 1e-9 ridge's bias, largest for planes near the origin:
    up to 0.6 mm here, median 2e-8 m); the in-plane spread test keeps or drops at eigh's spread."""
    rng = np.random.default_rng(2)
    points = _neighbourhoods(rng, 2000, "exact_plane")
    cloud, idx, dist = _as_map(points)
    planes = np.empty((len(idx), 4))
    kernels.fit_planes(cloud, idx, dist, 1.0, 1e9, 0.0, planes, None)
    centred = points - points.mean(axis=1, keepdims=True)
    w, V = np.linalg.eigh(np.einsum("nki,nkj->nij", centred, centred) / 5.0)
    assert np.all(np.abs(np.einsum("ni,ni->n", planes[:, :3], V[:, :, 0])) > 1 - 1e-9)
    offsets = np.abs(np.einsum("nki,ni->nk", points, planes[:, :3]) + planes[:, 3:])
    assert np.median(offsets) < 1e-7
    assert offsets.max() < 2e-3
    spread = w[:, 1]  # the smaller in-plane eigenvalue, m^2 (w[:, 0] ~ 0 across the plane)
    for factor, kept in ((0.999, True), (1.001, False)):
        for i in range(20):
            one = np.empty((1, 4))
            kernels.fit_planes(cloud, idx[i:i + 1], dist[:1], 1.0, 1e9, factor * np.sqrt(spread[i]), one, None)
            assert bool(~np.isnan(one[0, 0])) is kept


def test_line_fits_agree_with_eigh(kernels: ModuleType) -> None:
    """Centroid = the mean; direction = eigh's largest eigenvector; a line exactly where eigh's largest
    eigenvalue exceeds 3x the second (random blobs and lines: both answers occur)."""
    rng = np.random.default_rng(3)
    points = np.r_[_neighbourhoods(rng, 3000, "line"), _neighbourhoods(rng, 3000, "blob")]
    cloud, idx, dist = _as_map(points)
    lines = np.empty((len(idx), 6))
    kernels.fit_lines(cloud, idx, dist, 1.0, lines, None)
    centred = points - points.mean(axis=1, keepdims=True)
    w, V = np.linalg.eigh(np.einsum("nki,nkj->nij", centred, centred) / 5.0)
    ratio = w[:, 2] / w[:, 1]
    clear = np.abs(ratio - 3.0) > 1e-6  # away from the threshold, where rounding could decide
    kept = ~np.isnan(lines[:, 0])
    assert np.array_equal(kept[clear], (ratio > 3.0)[clear])
    assert 1000 < kept.sum() < 5000
    assert np.abs(lines[kept, :3] - points[kept].mean(axis=1)).max() < 1e-12
    assert np.all(np.abs(np.einsum("ni,ni->n", lines[kept, 3:], V[kept, :, 2])) > 1 - 1e-9)
    assert np.abs(np.linalg.norm(lines[kept, 3:], axis=1) - 1.0).max() < 1e-12


def test_degenerate_neighbourhoods_give_no_fit(kernels: ModuleType) -> None:
    """Coincident points: no line (isotropic, zero covariance) and, with a spread bound, no plane;
    collinear points: no plane once the spread bound applies (the normal could turn about the line);
    an unmatched feature (5th neighbour beyond the bound, its indices past the cloud's end): NaN,
    its indices not read; no features: nothing written."""
    t = np.linspace(0.0, 1.0, 5)[:, None]
    points = np.stack([np.full((5, 3), 7.5), [3.0, 4.0, -1.0] + t * [1.0, 2.0, 0.5]])
    cloud, idx, dist = _as_map(points)
    lines, planes = np.empty((2, 6)), np.empty((2, 4))
    kernels.fit_lines(cloud, idx, dist, 1.0, lines, None)
    assert np.isnan(lines[0]).all()
    assert not np.isnan(lines[1]).any()
    kernels.fit_planes(cloud, idx, dist, 1.0, 0.2, 0.05, planes, None)
    assert np.isnan(planes).all()
    unmatched_idx, unmatched_dist = np.full((1, 5), 10 ** 9, np.int64), np.full((1, 5), np.inf)
    kernels.fit_lines(cloud, unmatched_idx, unmatched_dist, 1.0, lines[:1], None)
    kernels.fit_planes(cloud, unmatched_idx, unmatched_dist, 1.0, 0.2, 0.0, planes[:1], None)
    assert np.isnan(lines[0]).all()
    assert np.isnan(planes[0]).all()
    empty_idx, empty_dist = np.zeros((0, 5), np.int64), np.zeros((0, 5))
    kernels.fit_planes(cloud, empty_idx, empty_dist, 1.0, 0.2, 0.0, np.empty((0, 4)), None)
    rows_J, rows_r = np.empty((0, 6)), np.empty(0)
    assert kernels.plane_rows(np.zeros((0, 3)), np.zeros(3), np.empty((0, 4)), 0.0, rows_J, rows_r) == 0
    assert kernels.edge_rows(np.zeros((0, 3)), np.zeros(3), np.empty((0, 6)), rows_J, rows_r) == 0


def test_fits_go_to_the_rows_given(kernels: ModuleType) -> None:
    rng = np.random.default_rng(4)
    cloud, idx, dist = _as_map(_neighbourhoods(rng, 50, "line"))
    every = np.empty((50, 6))
    kernels.fit_lines(cloud, idx, dist, 1.0, every, None)
    rows = rng.permutation(80)[:50].astype(np.int64)
    scattered = np.full((80, 6), -1.0)
    kernels.fit_lines(cloud, idx, dist, 1.0, scattered, rows)
    assert scattered[rows].tobytes() == every.tobytes()
    assert (np.delete(scattered, rows, axis=0) == -1.0).all()


def _rows_reference(q: np.ndarray, o: np.ndarray, n: np.ndarray, s: np.ndarray,
                    residual: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """LIO-SAM's rows: J = s [(q - o) x n, n], r = s residual."""
    return s[:, None] * np.c_[np.cross(q - o, n), n], s * residual


def test_plane_rows_against_numpy(kernels: ModuleType) -> None:
    rng = np.random.default_rng(5)
    q = rng.normal(size=(3000, 3)) * 15.0
    normals = rng.normal(size=(3000, 3)) * [1.0, 1.0, 3.0]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    planes = np.c_[normals, -np.einsum("ni,ni->n", normals, q) + rng.normal(scale=1.5, size=3000)]
    planes[::7] = np.nan  # no plane
    o = np.array([1.0, -2.0, 0.5])
    pd = np.einsum("ni,ni->n", planes[:, :3], q) + planes[:, 3]
    s = 1.0 - 0.9 * np.abs(pd) / np.sqrt(np.linalg.norm(q, axis=1) + 1e-9)
    keep = s > 0.1  # NaN rows compare False
    J_ref, r_ref = _rows_reference(q[keep], o, planes[keep, :3], s[keep], pd[keep])
    for min_normal_z in (0.0, 0.9):
        J, r = np.empty((3000, 6)), np.empty(3000)
        m = kernels.plane_rows(q, o, planes, min_normal_z, J, r)
        assert m == keep.sum()
        assert 500 < m < 2900
        ground = (np.abs(planes[keep, 2]) > 0.9) if min_normal_z else np.zeros(m, bool)
        assert 50 < ground.sum() < m or not min_normal_z
        expected = J_ref.copy()
        expected[np.ix_(ground, [2, 3, 4])] = 0.0  # ground rows keep z, roll and pitch only
        np.testing.assert_allclose(J[:m], expected, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(r[:m], r_ref, rtol=1e-12, atol=1e-15)


def test_edge_rows_against_numpy(kernels: ModuleType) -> None:
    rng = np.random.default_rng(6)
    q = rng.normal(size=(3000, 3)) * 15.0
    u = rng.normal(size=(3000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    lines = np.c_[q + rng.normal(scale=0.4, size=(3000, 3)), u]
    lines[::5] = np.nan
    lines[1] = np.r_[q[1] + 2.0 * u[1], u[1]]  # the point on its line: no direction, no row
    o = rng.normal(size=3)
    d = q - lines[:, :3]
    perp = d - np.einsum("ni,ni->n", d, u)[:, None] * u
    ld = np.linalg.norm(perp, axis=1)
    s = 1.0 - 0.9 * ld
    keep = (s > 0.1) & (ld >= 1e-9)
    J, r = np.empty((3000, 6)), np.empty(3000)
    m = kernels.edge_rows(q, o, lines, J, r)
    assert m == keep.sum()
    assert 500 < m < 2900
    J_ref, r_ref = _rows_reference(q[keep], o, perp[keep] / ld[keep, None], s[keep], ld[keep])
    np.testing.assert_allclose(J[:m], J_ref, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(r[:m], r_ref, rtol=1e-9, atol=1e-12)


def test_moved_lists_the_rows_beyond_the_distance(kernels: ModuleType) -> None:
    rng = np.random.default_rng(7)
    q = rng.normal(size=(5000, 3)) * 20.0
    at = q + rng.normal(scale=0.04, size=q.shape)
    out = np.empty(5000, np.int64)
    k = kernels.moved(q, at, 0.05, out)
    expected = np.flatnonzero(((q - at) ** 2).sum(axis=1) > 0.05 ** 2)
    assert 1000 < k < 4000
    assert np.array_equal(out[:k], expected)
    assert kernels.moved(q, q, 0.0, out) == 0


def test_wrong_arrays_are_refused(kernels: ModuleType) -> None:
    """A wrong dtype is a TypeError; a wrong shape, a non-contiguous or read-only output, an index
    outside the cloud or the fits a ValueError: nothing is read or written outside its array."""
    cloud, idx, dist = _as_map(_neighbourhoods(np.random.default_rng(8), 10, "plane"))
    planes = np.empty((10, 4))
    kernels.fit_planes(cloud, idx, dist, 1.0, 0.2, 0.0, planes, None)  # the right arrays pass
    with pytest.raises(TypeError):
        kernels.fit_planes(cloud.astype(np.float32), idx, dist, 1.0, 0.2, 0.0, planes, None)
    with pytest.raises(TypeError):
        kernels.fit_planes(cloud, idx.astype(np.int32), dist, 1.0, 0.2, 0.0, planes, None)
    with pytest.raises(TypeError):
        kernels.fit_lines(cloud, idx.astype(np.float64), dist, 1.0, np.empty((10, 6)), None)
    with pytest.raises(TypeError):
        kernels.moved(cloud, cloud, 0.1, np.empty(len(cloud), np.uint64))
    bad_shapes = [(cloud[:, :2].copy(), idx, dist, planes), (cloud, idx[:, :4].copy(), dist, planes),
                  (cloud, idx, dist[:9], planes), (cloud, idx, dist, np.empty((10, 6))),
                  (cloud, idx, dist, np.empty((9, 4))), (cloud.T, idx, dist, planes),
                  (cloud, idx, dist, np.empty((4, 10)).T)]
    for c, i, d, p in bad_shapes:
        with pytest.raises(ValueError, match=REFUSED):
            kernels.fit_planes(c, i, d, 1.0, 0.2, 0.0, p, None)
    readonly = np.empty((10, 4))
    readonly.flags.writeable = False
    for bad_idx, out, rows in [(idx + len(cloud), planes, None), (idx - len(cloud), planes, None),
                               (idx, planes, np.arange(10, dtype=np.int64) + 1), (idx, readonly, None)]:
        with pytest.raises(ValueError, match=REFUSED):
            kernels.fit_planes(cloud, bad_idx, dist, 1.0, 0.2, 0.0, out, rows)
    with pytest.raises(ValueError, match=REFUSED):  # J shorter than q
        kernels.plane_rows(cloud, np.zeros(3), np.zeros((len(cloud), 4)), 0.0, np.empty((3, 6)), np.empty(3))
    with pytest.raises(ValueError, match=REFUSED):  # origin not (3,)
        kernels.edge_rows(cloud, np.zeros(4), np.zeros((len(cloud), 6)), np.empty((50, 6)), np.empty(50))
    with pytest.raises(ValueError, match=REFUSED):
        kernels.moved(cloud, cloud[:-1], 0.1, np.empty(len(cloud), np.int64))


def test_scan_to_map_imports_no_numba() -> None:
    """Issue 30: matching runs on the C kernels; importing it loads no JIT (numba and LLVM: ~56 MB
    and ~0.5 s before the first sweep). Negative control: the same probe sees numba once imported."""
    probe = "import sys, {0}; print('numba' in sys.modules)"
    for module, expected in (("mrnc_eval.slam.scan_to_map", "False"), ("numba", "True")):
        run = subprocess.run([sys.executable, "-c", probe.format(module)], capture_output=True, text=True,
                             cwd=REPO, env={**os.environ, "PYTHONPATH": str(REPO)}, check=False)
        assert run.returncode == 0, run.stderr[-2000:]
        assert run.stdout.strip() == expected


def _longest_pause(work: Callable[[], object]) -> tuple[float, float]:
    """Run `work` in a thread while this thread spins: the longest gap (s) between two of this
    thread's iterations, and the work's duration (s). A call that holds the GIL stalls the spin
    for its whole duration; one that releases it, for about a switch interval."""
    done = threading.Event()

    def run() -> None:
        work()
        done.set()

    worker = threading.Thread(target=run)
    start = last = time.perf_counter()
    gap = 0.0
    worker.start()
    while not done.is_set():
        now = time.perf_counter()
        gap, last = max(gap, now - last), now
    worker.join()
    return gap, time.perf_counter() - start


def test_the_kernels_release_the_gil(kernels: ModuleType) -> None:
    """The reader thread decodes beside the matching: a fit over 400,000 features (~50 ms) leaves
    this thread running. Negative control: sorting a list (C, holding the GIL) stalls it."""
    rng = np.random.default_rng(10)
    cloud = rng.normal(size=(50_000, 3)) * 20.0
    idx = rng.integers(0, len(cloud), size=(400_000, 5))
    dist, lines = np.zeros((400_000, 5)), np.empty((400_000, 6))
    floats = rng.random(1_500_000).tolist()
    old = sys.getswitchinterval()
    sys.setswitchinterval(0.001)
    try:  # best of three: a loaded machine can deschedule this thread now and then
        fit = min(_longest_pause(lambda: kernels.fit_lines(cloud, idx, dist, 1.0, lines, None)) for _ in range(3))
        held = min(_longest_pause(lambda: sorted(floats)) for _ in range(3))
    finally:
        sys.setswitchinterval(old)
    assert fit[0] < 0.3 * fit[1], fit
    assert held[0] > 0.5 * held[1], held
