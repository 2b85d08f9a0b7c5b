"""slam/_match_kernels.c, scan-to-map matching's map search, fits and rows: against numpy references
(the 5 nearest neighbours against brute force; the plane fit's arithmetic transcribed to numpy's
element-wise operations gives the same bits; line and plane fits against np.linalg.eigh), on
degenerate neighbourhoods, and refusing arrays it would misread.
Built here from this tree's source with -O3 -march=native (FMA available to the compiler, so the
no-contraction pragma is tested too)."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

import mrnc_eval.slam
from tests.c_build import build_extension

SOURCE = Path(mrnc_eval.slam.__file__).with_name("_match_kernels.c")
REPO = Path(__file__).resolve().parents[2]
# the kernels' messages for a wrong shape, length or index, and numpy's for a wrong layout or a read-only output
REFUSED = "expected|differ|outside|must|contiguous|read-only|many"


@pytest.fixture(scope="module")
def kernels(tmp_path_factory: pytest.TempPathFactory) -> ModuleType:
    return build_extension(SOURCE, "mrnc_eval.slam._match_kernels", tmp_path_factory.mktemp("match_kernels"),
                           ("-O3", "-march=native"))


def _neighbourhoods(rng: np.random.Generator, n: int, shape: str) -> np.ndarray:
    """(n, 5, 3) neighbourhoods on a grid 5 m apart, 5-60 m from the origin: "plane" (2 cm noise off
    a random plane), "line" (3 cm noise about a random line), "blob" (isotropic), "exact_plane"."""
    side = int(np.ceil(n ** (1 / 3)))
    centre = (np.stack(np.unravel_index(np.arange(n), (side,) * 3), axis=1) * 5.0 + 5.0)[:, None, :]
    basis = np.linalg.qr(rng.normal(size=(n, 3, 3)))[0]
    local = rng.normal(size=(n, 5, 3)) * {"plane": [0.3, 0.3, 0.02], "line": [0.4, 0.03, 0.03],
                                         "blob": [0.2, 0.2, 0.2], "exact_plane": [0.3, 0.3, 0.0]}[shape]
    return np.asarray(centre + np.einsum("nkj,nij->nki", local, basis), np.float64)


def _brute_force(cloud: np.ndarray, q: np.ndarray, max_dist: float) -> tuple[np.ndarray, np.ndarray]:
    """The 5 nearest points of each q (n, 5, 3) and their distances (n, 5), nearest first, d^2 summed
    as the search does ((dx^2 + dy^2) + dz^2); NaN / inf past the last one within max_dist."""
    near, dist = np.empty((len(q), 5, 3)), np.empty((len(q), 5))
    for lo in range(0, len(q), 200):
        d = q[lo:lo + 200, None, :] - cloud[None, :, :]
        sq = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2]
        order = np.argsort(sq, axis=1, kind="stable")[:, :5]
        near[lo:lo + 200], dist[lo:lo + 200] = cloud[order], np.sqrt(np.take_along_axis(sq, order, axis=1))
    beyond = ~(dist < max_dist)
    near[beyond], dist[beyond] = np.nan, np.inf
    return near, dist


def _planes_same_ops(p: np.ndarray, max_offset: float, min_spread: float) -> np.ndarray:
    """fit_planes' arithmetic on the neighbourhoods p (n, 5, 3), operation by operation, in numpy
    (element-wise: no FMA, IEEE rounding)."""
    n = len(p)
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


def _map(kernels: ModuleType, points: np.ndarray) -> tuple[np.ndarray, object, np.ndarray]:
    """The neighbourhoods (n, 5, 3) as one map cloud, its tree, and a query at each one's centroid."""
    cloud = points.reshape(-1, 3).copy()
    return cloud, kernels.build_tree(cloud), points.mean(axis=1)


@pytest.mark.parametrize("shape", ["blob", "plane", "line"])
def test_the_search_finds_the_brute_force_neighbours(kernels: ModuleType, shape: str) -> None:
    """The 5 nearest map points, nearest first, and whether the 5th is within max_dist: queries at
    the neighbourhoods, between them and far off (the bound cuts some)."""
    rng = np.random.default_rng(0)
    cloud, tree, centres = _map(kernels, _neighbourhoods(rng, 1000, shape))
    q = np.r_[centres, centres + rng.normal(scale=2.0, size=centres.shape), rng.uniform(-20, 80, (500, 3))]
    got, dist = np.empty((len(q), 15)), np.empty((len(q), 5))
    for max_dist in (1.0, 3.0):
        kernels.neighbours(tree, q, max_dist, got, dist)
        near, expected = _brute_force(cloud, q, max_dist)
        assert np.array_equal(dist, expected)
        assert np.array_equal(got.reshape(-1, 5, 3), near, equal_nan=True)
        assert 0.2 < np.isinf(dist[:, 4]).mean() < 0.8  # the bound decides for many queries


def test_the_search_with_repeated_coordinates(kernels: ModuleType) -> None:
    """Points on a coarse lattice (many equal coordinates and equal distances; a block of 40
    identical points): the distances found are brute force's; ties may come in another order."""
    rng = np.random.default_rng(11)
    cloud = np.r_[rng.integers(0, 6, size=(3000, 3)) * 0.5, np.full((40, 3), 1.25)]
    tree = kernels.build_tree(cloud)
    q = rng.uniform(-0.5, 3.0, size=(2000, 3))
    got, dist = np.empty((len(q), 15)), np.empty((len(q), 5))
    kernels.neighbours(tree, q, 2.0, got, dist)
    _, expected = _brute_force(cloud, q, 2.0)
    assert np.array_equal(dist, expected)
    found = np.linalg.norm(got.reshape(-1, 5, 3) - q[:, None, :], axis=2)
    np.testing.assert_allclose(found, dist, rtol=1e-15)


@pytest.mark.parametrize("shape", ["plane", "line", "blob", "exact_plane"])
def test_plane_fits_give_the_bits_of_their_arithmetic_in_numpy(kernels: ModuleType, shape: str) -> None:
    rng = np.random.default_rng(1)
    _, tree, q = _map(kernels, _neighbourhoods(rng, 4000, shape))
    found, dist = np.empty((len(q), 15)), np.empty((len(q), 5))
    kernels.neighbours(tree, q, 2.0, found, dist)  # the search: against brute force above
    near = found.reshape(-1, 5, 3)
    assert not np.isnan(near).any()
    for max_offset, min_spread in ((0.2, 0.0), (0.05, 0.05), (1e9, 0.2)):
        planes = np.empty((len(q), 4))
        kernels.fit_planes(tree, q, 2.0, max_offset, min_spread, planes, None)
        with np.errstate(all="ignore"):
            expected = _planes_same_ops(near, max_offset, min_spread)
        assert planes.tobytes() == expected.tobytes()


def test_plane_fits_agree_with_eigh(kernels: ModuleType) -> None:
    """Noise-free planar neighbourhoods: the fitted normal is the covariance's smallest eigenvector
    and the points lie on the plane (to the conditioning of the normal equations);
    the in-plane spread test keeps or drops at eigh's spread."""
    rng = np.random.default_rng(2)
    points = _neighbourhoods(rng, 2000, "exact_plane")
    _, tree, q = _map(kernels, points)
    planes = np.empty((len(q), 4))
    kernels.fit_planes(tree, q, 2.0, 1e9, 0.0, planes, None)
    centred = points - points.mean(axis=1, keepdims=True)
    w, V = np.linalg.eigh(np.einsum("nki,nkj->nij", centred, centred) / 5.0)
    # angle between the normals, rad: LIO-SAM's A x = -1 loses digits on small patches far from the
    # origin (here 0.3 m patches 5-80 m off: median 6e-8, max 3e-4 rad)
    angle = np.linalg.norm(np.cross(planes[:, :3], V[:, :, 0]), axis=1)
    assert np.median(angle) < 1e-6
    assert angle.max() < 1e-3
    offsets = np.abs(np.einsum("nki,ni->nk", points, planes[:, :3]) + planes[:, 3:])
    # the same conditioning, in metres: median 1e-6, 99th percentile 0.7 mm, max 9 mm (a patch 80 m off)
    assert np.median(offsets) < 2e-6
    assert np.percentile(offsets, 99) < 1.5e-3
    spread = w[:, 1]  # the smaller in-plane eigenvalue, m^2 (w[:, 0] ~ 0 across the plane)
    for factor, kept in ((0.999, True), (1.001, False)):
        one = np.empty((20, 4))
        for i in range(20):
            kernels.fit_planes(tree, q[i:i + 1], 2.0, 1e9, factor * np.sqrt(spread[i]), one[i:i + 1], None)
        assert (~np.isnan(one[:, 0]) == kept).all()


def test_line_fits_agree_with_eigh(kernels: ModuleType) -> None:
    """Centroid = the mean; direction = eigh's largest eigenvector; a line exactly where eigh's largest
    eigenvalue exceeds 3x the second (random blobs and lines: both answers occur)."""
    rng = np.random.default_rng(3)
    points = np.r_[_neighbourhoods(rng, 3000, "line"), _neighbourhoods(rng, 3000, "blob") + [0.0, 0.0, 100.0]]
    _, tree, q = _map(kernels, points)
    lines = np.empty((len(q), 6))
    kernels.fit_lines(tree, q, 2.0, lines, None)
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
    """Coincident points: no line (zero covariance) and, with a spread bound, no plane; collinear
    points: a line, and no plane once the spread bound applies (the normal could turn about the
    line); a feature whose 5th neighbour is beyond max_dist: NaN; no features: nothing written."""
    t = np.linspace(0.0, 1.0, 5)[:, None]
    points = np.stack([np.full((5, 3), 7.5), [3.0, 4.0, -1.0] + t * [1.0, 2.0, 0.5]])
    _, tree, q = _map(kernels, points)
    lines, planes = np.empty((2, 6)), np.empty((2, 4))
    kernels.fit_lines(tree, q, 1.5, lines, None)
    assert np.isnan(lines[0]).all()
    assert not np.isnan(lines[1]).any()
    kernels.fit_planes(tree, q, 1.5, 0.2, 0.05, planes, None)
    assert np.isnan(planes).all()
    kernels.fit_lines(tree, q, 1.1, lines, None)  # the collinear points' ends are 1.146 m from their middle
    assert np.isnan(lines[1]).all()
    kernels.fit_lines(tree, q + 100.0, 1.5, lines, None)
    assert np.isnan(lines).all()
    kernels.fit_planes(tree, np.zeros((0, 3)), 1.0, 0.2, 0.0, np.empty((0, 4)), None)
    rows_J, rows_r = np.empty((0, 6)), np.empty(0)
    assert kernels.plane_rows(np.zeros((0, 3)), np.zeros(3), np.empty((0, 4)), 0.0, rows_J, rows_r) == 0
    assert kernels.edge_rows(np.zeros((0, 3)), np.zeros(3), np.empty((0, 6)), rows_J, rows_r) == 0


def test_fits_go_to_the_rows_given(kernels: ModuleType) -> None:
    rng = np.random.default_rng(4)
    _, tree, q = _map(kernels, _neighbourhoods(rng, 50, "line"))
    every = np.empty((50, 6))
    kernels.fit_lines(tree, q, 2.0, every, None)
    rows = rng.permutation(80)[:50].astype(np.int64)
    scattered = np.full((80, 6), -1.0)
    kernels.fit_lines(tree, q, 2.0, scattered, rows)
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
    """A wrong dtype is a TypeError; a wrong shape, a non-contiguous or read-only output, a row
    outside the fits, something else than a tree a ValueError: nothing is read or written outside
    its array."""
    cloud, tree, q = _map(kernels, _neighbourhoods(np.random.default_rng(8), 10, "plane"))
    planes = np.empty((10, 4))
    kernels.fit_planes(tree, q, 1.0, 0.2, 0.0, planes, None)  # the right arrays pass
    with pytest.raises(TypeError):
        kernels.fit_planes(tree, q.astype(np.float32), 1.0, 0.2, 0.0, planes, None)
    with pytest.raises(TypeError):
        kernels.build_tree(cloud.astype(np.float32))
    with pytest.raises(TypeError):
        kernels.fit_lines(tree, q, 1.0, np.empty((10, 6)), np.arange(10, dtype=np.int32))
    with pytest.raises(TypeError):
        kernels.moved(cloud, cloud, 0.1, np.empty(len(cloud), np.uint64))
    readonly = np.empty((10, 4))
    readonly.flags.writeable = False
    for bad_q, out, rows in [(q[:, :2].copy(), planes, None), (q[:9], planes, None), (q, np.empty((10, 6)), None),
                             (q.T, planes, None), (q, np.empty((4, 10)).T, None), (q, readonly, None),
                             (q, planes, np.arange(10, dtype=np.int64) + 1), (q, planes, -np.ones(10, np.int64))]:
        with pytest.raises(ValueError, match=REFUSED):
            kernels.fit_planes(tree, bad_q, 1.0, 0.2, 0.0, out, rows)
    for not_a_tree in (cloud, None, np.zeros(3)):
        with pytest.raises(ValueError, match=r"[Cc]apsule"):
            kernels.fit_planes(not_a_tree, q, 1.0, 0.2, 0.0, planes, None)
    with pytest.raises(ValueError, match=REFUSED):
        kernels.build_tree(cloud[:, :2].copy())
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
    """The reader thread decodes beside the matching: searches and fits for 400,000 features
    (~0.2 s) leave this thread running. Negative control: sorting a list (C, holding the GIL) stalls it."""
    rng = np.random.default_rng(10)
    cloud = rng.normal(size=(50_000, 3)) * 20.0
    tree, q, lines = kernels.build_tree(cloud), rng.normal(size=(400_000, 3)) * 20.0, np.empty((400_000, 6))
    floats = rng.random(1_500_000).tolist()
    old = sys.getswitchinterval()
    sys.setswitchinterval(0.001)
    try:  # best of three: a loaded machine can deschedule this thread now and then
        fit = min(_longest_pause(lambda: kernels.fit_lines(tree, q, 3.0, lines, None)) for _ in range(3))
        held = min(_longest_pause(lambda: sorted(floats)) for _ in range(3))
    finally:
        sys.setswitchinterval(old)
    assert fit[0] < 0.3 * fit[1], fit
    assert held[0] > 0.5 * held[1], held
