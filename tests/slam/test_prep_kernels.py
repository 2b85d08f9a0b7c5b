"""slam/_prep_kernels.c (range image, deskew, feature labels, ground test, voxel centroids, gyro
track; issue 30: they replaced numba kernels, so a SLAM run loads no LLVM) against plain numpy or
Python references in the same arithmetic: the same bits, on random and edge-case inputs (empty,
one point, NaN coordinates, ties in curvature). Built here from this tree's source with -O3
-march=native (FMA available: the no-contraction pragma is tested too). Wrong dtypes, shapes,
layouts and indices raise instead of reading or writing outside an array."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from mrnc_eval.data import Sweep
from mrnc_eval.slam import features, range_image
from mrnc_eval.slam.config import SlamConfig
from tests.c_build import build_extension

REPO = Path(__file__).resolve().parents[2]
SOURCE = REPO / "mrnc_eval" / "slam" / "_prep_kernels.c"


@pytest.fixture(scope="module")
def pk(tmp_path_factory: pytest.TempPathFactory) -> ModuleType:
    return build_extension(SOURCE, "mrnc_eval.slam._prep_kernels", tmp_path_factory.mktemp("prep"),
                           ("-O3", "-march=native", "-fwrapv", "-Wall"))


def _clouds(rng: np.random.Generator) -> list[np.ndarray]:
    """(n, 3) clouds: empty, one point, random with NaN and inf rows, in float32 and float64."""
    big = rng.normal(scale=15.0, size=(3000, 3))
    big[rng.integers(0, 3000, 20)] = np.nan
    big[5] = [np.inf, 0.0, 0.0]
    clouds = [np.zeros((0, 3)), np.array([[1.0, 2.0, 0.5]]), big]
    return clouds + [c.astype(np.float32) for c in clouds]


def _same(a: np.ndarray, b: np.ndarray) -> None:
    assert a.dtype == b.dtype
    assert a.shape == b.shape
    assert a.tobytes() == b.tobytes()  # the bits (NaN included)


def test_range_and_keep_gives_numpys_ranges_and_mask(pk: ModuleType) -> None:
    rng = np.random.default_rng(1)
    box = (-1.0, -2.0, -0.5, 3.0, 1.0, 0.5)
    for cloud in _clouds(rng):
        p = cloud.astype(np.float64)
        r = np.sqrt(p[:, 0] * p[:, 0] + p[:, 1] * p[:, 1] + p[:, 2] * p[:, 2])
        inside = np.all((p >= box[:3]) & (p <= box[3:]), axis=1)
        for b in (box, None):
            keep, ranges = np.empty(len(p), bool), np.empty(len(p))
            pk.range_and_keep(cloud, keep, ranges, 0.5, 30.0, b)
            _same(ranges, r)
            expected = np.isfinite(r) & (r >= 0.5) & (r <= 30.0) & (~inside if b is not None else True)
            _same(keep, expected)


def test_pixel_order_and_gather_give_numpys_indexing(pk: ModuleType) -> None:
    rng = np.random.default_rng(2)
    for n in (0, 1, 2000):
        cloud = rng.normal(size=(n, 3)).astype(np.float32)
        keep = rng.random(n) < 0.8
        ring, column = rng.integers(0, 32, n), rng.integers(0, 512, n)
        for order in (np.arange(n), np.lexsort((column, ring))):  # unordered, then ring-major
            ring, column, keep = ring[order], column[order], keep[order]
            for rate in (1, 2, 3):
                idx = np.empty(n, np.int64)
                m, ordered = pk.kept_in_pixel_order(keep, ring, column, 512, rate, idx)
                want = np.flatnonzero(keep & (ring % rate == 0))
                _same(idx[:m], want)
                pixel = ring[want] * 512 + column[want]
                assert ordered == bool(np.all(np.diff(pixel) > 0))
                ranges, t = rng.random(n), rng.random(n).astype(np.float32)
                out = (np.empty((m, 3)), np.empty(m, np.int64), np.empty(m, np.int64), np.empty(m), np.empty(m))
                pk.gather(cloud, ring, column, ranges, t, want, rate, *out)
                for got, exp in zip(out, (cloud[want].astype(np.float64), ring[want] // rate, column[want],
                                          ranges[want], t[want].astype(np.float64)), strict=True):
                    _same(got, exp)
                no_time = (np.empty((m, 3)), np.empty(m, np.int64), np.empty(m, np.int64), np.empty(m), np.empty(0))
                pk.gather(cloud, ring, column, ranges, np.zeros(0), want, rate, *no_time)  # clouds without time
                _same(no_time[0], out[0])


def test_deskew_gives_numpys_rotation_and_motion(pk: ModuleType) -> None:
    rng = np.random.default_rng(3)
    for n in (0, 1, 5000):
        p, t = rng.normal(scale=20.0, size=(n, 3)), rng.uniform(0.0, 0.1, n)
        t0 = float(t.min()) if n else 0.0
        table = np.linalg.qr(rng.normal(size=(101, 3, 3)))[0]
        v, acc = rng.normal(size=3), rng.normal(size=3)
        out = np.empty((n, 3))
        pk.deskew_apply(p, t, t0 + 0.01, table, tuple(v), tuple(acc), out)  # t0 later: clamping at 0 too
        k = np.clip(np.floor((t - (t0 + 0.01)) / 1e-3 + 0.5).astype(np.int64), 0, len(table) - 1)
        r = table[k]
        want = np.stack([r[:, a, 0] * p[:, 0] + r[:, a, 1] * p[:, 1] + r[:, a, 2] * p[:, 2] + v[a] * t
                         + 0.5 * acc[a] * t * t for a in range(3)], axis=1).reshape(n, 3)
        _same(out, want)


def test_smoothness_gives_numpys_sums(pk: ModuleType) -> None:
    rng = np.random.default_rng(4)
    for n in (0, 1, 10, 11, 3000):
        r, xyz = rng.uniform(0.5, 40.0, n), rng.normal(scale=10.0, size=(n, 3))
        if n > 20:
            xyz[15] = 0.0  # |p| = 0: curvature 0, no division
        i = np.arange(5, n - 5)
        d = -10.0 * r[i]
        dp = 10.0 * xyz[i]
        for k in range(1, 6):
            d = d + (r[i - k] + r[i + k])
            dp = dp - (xyz[i - k] + xyz[i + k])
        norm = np.sqrt(xyz[i, 0] * xyz[i, 0] + xyz[i, 1] * xyz[i, 1] + xyz[i, 2] * xyz[i, 2])
        acc = dp[:, 0] * dp[:, 0] + dp[:, 1] * dp[:, 1] + dp[:, 2] * dp[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            paper = np.where(norm > 0, np.sqrt(acc) / (10.0 * norm), 0.0)
        for flag, values in ((False, d * d), (True, paper)):
            want = np.zeros(n)
            want[i] = values
            out = np.full(n, np.nan)
            pk.smoothness(r, xyz, flag, out)
            _same(out, want)


def _unreliable(r: np.ndarray, col: np.ndarray, cfg: dict[str, float]) -> np.ndarray:
    """LIO-SAM's occluded and parallel-beam points, in plain Python."""
    n = r.size
    picked = np.zeros(n, bool)
    for i in range(5, n - 6):
        if abs(col[i + 1] - col[i]) < 10:
            if r[i] - r[i + 1] > cfg["occ"]:
                picked[i - 5:i + 1] = True
            elif r[i + 1] - r[i] > cfg["occ"]:
                picked[i + 1:i + 7] = True
    for i in range(5, n - 6):
        if abs(r[i - 1] - r[i]) > cfg["par"] * r[i] and abs(r[i + 1] - r[i]) > cfg["par"] * r[i]:
            picked[i] = True
    return picked


def _block(picked: np.ndarray, col: np.ndarray, i: int) -> None:
    picked[i] = True
    for step in (1, -1):
        for k in range(1, 6):
            j = i + step * k
            if not (0 <= j < col.size and abs(col[j] - col[j - step]) <= 10):
                break
            picked[j] = True


def _stable(a: np.ndarray) -> np.ndarray:
    return np.argsort(a, kind="stable")


def _reference_sector(curv: np.ndarray, col: np.ndarray, state: tuple[np.ndarray, np.ndarray],
                      sector: tuple[int, int], cfg: dict[str, float], *, argsort: Callable[[np.ndarray], np.ndarray]
                      ) -> None:
    picked, label = state
    sp, ep = sector
    order = argsort(curv[sp:ep + 1]) + sp
    count = 0
    for i in order[::-1]:
        if picked[i] or curv[i] <= cfg["edge"]:
            continue
        count += 1
        if count > cfg["max_edges"]:
            break
        label[i] = 1
        _block(picked, col, i)
    for i in order:
        if not picked[i] and curv[i] < cfg["surf"]:
            label[i] = -1
            _block(picked, col, i)
    seg = label[sp:ep + 1]
    seg[seg == 0] = -2


def _reference_labels(image: tuple[np.ndarray, np.ndarray, np.ndarray], bounds: tuple[np.ndarray, np.ndarray],
                      cfg: dict[str, float], *, argsort: Callable[[np.ndarray], np.ndarray] = _stable
                      ) -> np.ndarray:
    """LIO-SAM's selection in plain Python (by default with a stable sort: the same order as any
    sort when the curvatures are distinct)."""
    r, curv, col = image
    picked, label = _unreliable(r, col, cfg), np.zeros(r.size, np.int8)
    sectors = int(cfg["sectors"])
    for s, e in zip(*bounds, strict=True):
        if e - s < 6 * sectors:
            continue
        for j in range(sectors):
            sp, ep = (s * (sectors - j) + e * j) // sectors, (s * (sectors - 1 - j) + e * (j + 1)) // sectors - 1
            if sp < ep:
                _reference_sector(curv, col, (picked, label), (sp, ep), cfg, argsort=argsort)
    return label


def _image(rng: np.random.Generator, rings: int, width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A ring-major image with walls, occlusion jumps and column gaps: ranges, columns, ring starts, counts."""
    cols, ranges = [np.zeros(0, np.int64)], [np.zeros(0)]
    for _ in range(rings):
        c = np.sort(rng.choice(width, int(rng.integers(0, width)), replace=False))
        r = 5.0 + np.cumsum(rng.normal(scale=0.05, size=c.size)) + np.where(rng.random(c.size) < 0.03, 4.0, 0.0)
        cols.append(c)
        ranges.append(np.abs(r) + 0.5)
    counts = np.array([c.size for c in cols[1:]], np.int64)
    starts = np.cumsum(counts) - counts
    return np.concatenate(ranges), np.concatenate(cols).astype(np.int64), starts, counts


CFG = {"edge": 1.0, "surf": 0.1, "max_edges": 20, "sectors": 6, "occ": 0.3, "par": 0.02}


def _labels(pk: ModuleType, image: tuple[np.ndarray, np.ndarray, np.ndarray], bounds: tuple[np.ndarray, np.ndarray],
            cfg: dict[str, float]) -> np.ndarray:
    r, curv, col = image
    out = np.full(r.size, 7, np.int8)
    pk.extract(r, curv, col, bounds[0], bounds[1], cfg["edge"], cfg["surf"], int(cfg["max_edges"]),
               int(cfg["sectors"]), cfg["occ"], cfg["par"], out)
    return out


def test_feature_labels_give_lio_sams_selection(pk: ModuleType) -> None:
    rng = np.random.default_rng(5)
    for rings, width in ((0, 64), (1, 20), (4, 300), (16, 1024)):
        r, col, starts, counts = _image(rng, rings, width)
        curv = np.empty(r.size)
        pk.smoothness(r, np.zeros((r.size, 3)), False, curv)
        curv += rng.uniform(0, 1e-9, r.size)  # distinct: any sort gives the same order
        bounds = (starts + 5, starts + counts - 6)
        for sectors in (1, 6):
            cfg = {**CFG, "sectors": sectors}
            got = _labels(pk, (r, curv, col), bounds, cfg)
            _same(got, _reference_labels((r, curv, col), bounds, cfg))
        if rings == 16:
            assert {-2, -1, 1} <= set(np.unique(got))  # edges and both kinds of planar points occur


def test_ties_in_curvature_rank_as_numbas_quicksort(pk: ModuleType) -> None:
    """Equal curvatures (here rounded to 0.1 m^2) are ranked by numba's np.argsort, a quicksort
    (unstable), so the labels are the numba kernel's: the reference sorts with numba's own
    quicksort (its Python form), and a stable sort (the negative control) ranks the ties differently."""
    quicksort = pytest.importorskip("numba.misc.quicksort", reason="numba: the reference sort of the ties")
    numba_support = pytest.importorskip("numba.np.numpy_support")
    numba_sort = quicksort.make_py_quicksort(lt=numba_support.lt_floats, is_argsort=True, is_np_array=True)
    r, col, starts, counts = _image(np.random.default_rng(6), 16, 1024)
    curv = np.empty(r.size)
    pk.smoothness(r, np.zeros((r.size, 3)), False, curv)
    curv = np.round(curv, 1)
    curv[::97] = np.nan  # NaN sorts last, as in numpy and numba
    bounds = (starts + 5, starts + counts - 6)
    got = _labels(pk, (r, curv, col), bounds, CFG)
    stable = _reference_labels((r, curv, col), bounds, CFG)
    numba_order = _reference_labels((r, curv, col), bounds, CFG, argsort=numba_sort.run_quicksort)
    _same(got, numba_order)
    assert not np.array_equal(got, stable)


def test_vertical_neighbours_and_ground_test_give_numpys(pk: ModuleType) -> None:
    rng = np.random.default_rng(7)
    for n in (1, 4000):
        ring, col = rng.integers(0, 16, n), rng.integers(0, 300, n)
        keep = np.unique(ring * 300 + col, return_index=True)[1]  # one point per pixel, ring-major
        ring, col = ring[keep], col[keep]
        grid = np.full((17, 300), -1, np.int64)
        grid[ring, col] = np.arange(ring.size)
        out = np.empty((ring.size, 2), np.int64)
        pk.vertical_neighbours(ring, col, int(ring.max()) + 1, int(col.max()) + 1, out)
        up = np.where(ring > 0, grid[np.maximum(ring - 1, 0), col], -1)
        down = np.where(ring + 1 <= ring.max(), grid[ring + 1, col], -1)
        _same(out, np.stack([up, down], axis=1))
        points = rng.normal(size=(ring.size, 3)) * [5.0, 5.0, 0.3] - [0.0, 0.0, 1.0]
        image = range_image.RangeImage(points=points, ring=ring, column=col, range_m=np.linalg.norm(points, axis=1),
                                       point_time=None)
        everyone = np.arange(ring.size)
        flat = np.empty(ring.size, bool)
        pk.ground_of(points, everyone, out, 0.1, flat)
        _same(flat, features.ground_mask(image, points, math.degrees(math.atan(0.1))))


def test_voxel_centroids_give_numpys_first_seen_means(pk: ModuleType) -> None:
    rng = np.random.default_rng(8)
    for n, leaf in ((1, 0.5), (2, 1e-9), (5000, 0.3), (5000, 4.0)):
        p = rng.normal(scale=3.0, size=(n, 3))
        out = np.frombuffer(pk.voxel_centroids(p, leaf), np.float64).reshape(-1, 3)
        keys = np.floor(p / leaf).astype(np.int64)
        _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
        rank = np.argsort(np.argsort(first))  # voxels in first-seen order
        sums, counts = np.zeros((first.size, 3)), np.zeros(first.size, np.int64)
        np.add.at(sums, rank[inverse.ravel()], p)  # sequential, point after point
        np.add.at(counts, rank[inverse.ravel()], 1)
        _same(out, sums / counts[:, None])
    assert len(pk.voxel_centroids(np.zeros((0, 3)), 1.0)) == 0


def test_gyro_track_gives_the_python_quaternion_product(pk: ModuleType) -> None:
    rng = np.random.default_rng(9)
    for n in (0, 1, 500):
        gyro, dt = rng.normal(scale=2.0, size=(n, 3)), rng.uniform(0.0, 0.02, n)
        if n > 10:
            gyro[3:6] = 1e-13  # below the small-angle threshold
        q = np.zeros((n, 4))
        pk.integrate_gyro(gyro, dt, q)
        want = [[1.0, 0.0, 0.0, 0.0]][:n]
        for i in range(n - 1):
            w = [float(g) * float(dt[i]) for g in gyro[i]]
            ang = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
            if ang > 1e-12:
                s = math.sin(0.5 * ang) / ang
                d = [math.cos(0.5 * ang), w[0] * s, w[1] * s, w[2] * s]
            else:
                d = [1.0, 0.5 * w[0], 0.5 * w[1], 0.5 * w[2]]
            a = want[-1]
            e = [a[0] * d[0] - a[1] * d[1] - a[2] * d[2] - a[3] * d[3],
                 a[0] * d[1] + a[1] * d[0] + a[2] * d[3] - a[3] * d[2],
                 a[0] * d[2] - a[1] * d[3] + a[2] * d[0] + a[3] * d[1],
                 a[0] * d[3] + a[1] * d[2] - a[2] * d[1] + a[3] * d[0]]
            nrm = math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2] + e[3] * e[3])
            want.append([x / nrm for x in e])
        _same(q, np.array(want, np.float64).reshape(n, 4))


def test_wrong_dtypes_shapes_layouts_and_indices_raise(pk: ModuleType) -> None:
    n = 50
    p, r, t = np.zeros((n, 3)), np.ones(n), np.zeros(n)
    ring, col = np.zeros(n, np.int64), np.arange(n, dtype=np.int64)
    keep, out3 = np.ones(n, bool), np.zeros((n, 3))  # not empty: garbage cast to float32 overflows
    cases = [
        (TypeError, lambda: pk.range_and_keep(p.astype(np.int32), keep, r.copy(), 0.0, 1.0, None)),  # dtype
        (TypeError, lambda: pk.range_and_keep(p, keep.astype(np.int8), r.copy(), 0.0, 1.0, None)),
        (TypeError, lambda: pk.range_and_keep([[1.0, 2.0, 3.0]], keep, r.copy(), 0.0, 1.0, None)),  # not an array
        (ValueError, lambda: pk.range_and_keep(np.zeros((n, 4)), keep, r.copy(), 0.0, 1.0, None)),  # shape
        (ValueError, lambda: pk.range_and_keep(p, keep[:-1], r.copy(), 0.0, 1.0, None)),  # length
        (ValueError, lambda: pk.range_and_keep(np.zeros((n, 6))[:, ::2], keep, r.copy(), 0.0, 1.0, None)),  # strides
        (TypeError, lambda: pk.range_and_keep(p, keep, r.copy(), 0.0, 1.0, (1.0, 2.0))),  # box of 2
        (TypeError, lambda: pk.smoothness(r, p, False, np.zeros(n).view(np.int64))),
        (TypeError, lambda: pk.deskew_apply(p, t, 0.0, np.eye(3)[None], (0, 0, 0), (0, 0, 0), out3.astype(np.float32))),
        (ValueError, lambda: pk.deskew_apply(p, t, 0.0, np.eye(3)[None], (0, 0, 0), (0, 0, 0), np.empty((3, n)).T)),
        (ValueError, lambda: pk.deskew_apply(p, t, 0.0, np.zeros((0, 3, 3)), (0, 0, 0), (0, 0, 0), out3)),
        (ValueError, lambda: pk.deskew_apply(p, t, 0.0, np.zeros((2, 3, 4)), (0, 0, 0), (0, 0, 0), out3)),
        (ValueError, lambda: pk.gather(p, ring, col, r, t, np.array([0, n]), 1, *_outs(2))),  # idx past the end
        (ValueError, lambda: pk.gather(p, ring, col, r, t[:3], np.array([0]), 1, *_outs(1))),  # times for 3 of n
        (ValueError, lambda: pk.kept_in_pixel_order(keep, ring, col, n, 0, np.empty(n, np.int64))),  # rate 0
        (ValueError, lambda: pk.vertical_neighbours(ring - 1, col, 1, n, np.empty((n, 2), np.int64))),  # row -1
        (ValueError, lambda: pk.vertical_neighbours(ring, col, 1, n - 1, np.empty((n, 2), np.int64))),  # col >= width
        (ValueError, lambda: pk.ground_of(p, np.array([n]), np.full((n, 2), -1), 0.1, np.empty(1, bool))),
        (ValueError, lambda: pk.ground_of(p, np.array([0]), np.full((n, 2), n), 0.1, np.empty(1, bool))),
        (ValueError, lambda: pk.extract(r, r, col, np.array([-5]), np.array([n]), 1.0, 0.1, 20, 1, 0.3, 0.02,
                                        np.empty(n, np.int8))),  # a ring starting before the array
        (ValueError, lambda: pk.extract(r, r, col, np.array([0]), np.array([n + 1]), 1.0, 0.1, 20, 1, 0.3, 0.02,
                                        np.empty(n, np.int8))),
        (ValueError, lambda: pk.voxel_centroids(p, 0.0)),
        (TypeError, lambda: pk.integrate_gyro(p, t, np.zeros((n, 4), np.float32))),
        (ValueError, lambda: pk.integrate_gyro(p, t[:-1], np.zeros((n, 4)))),
    ]
    assert [i for i, (error, call) in enumerate(cases) if not _raises(call, error)] == []
    read_only = np.empty(n)
    read_only.flags.writeable = False
    with pytest.raises(TypeError, match="writable"):
        pk.smoothness(r, p, False, read_only)


def _raises(call: Callable[[], object], error: type[Exception]) -> bool:
    """True when call() raises `error` (another exception propagates: a wrong type fails the test)."""
    try:
        call()
    except error:
        return True
    return False


def _outs(m: int) -> tuple[np.ndarray, ...]:
    return np.empty((m, 3)), np.empty(m, np.int64), np.empty(m, np.int64), np.empty(m), np.empty(m)


def test_the_wrappers_normalise_what_the_reader_hands_out() -> None:
    """project/extract_features take the reader's dtypes (float32 points and times, uint16 rings,
    uint32 columns) and the SLAM's float64 arrays, as the numba kernels did."""
    from mrnc_eval.slam.warmup import room_sweep

    cfg = SlamConfig()
    sweep = room_sweep()
    image = range_image.project(sweep, cfg.sensor, cfg.features)
    as64 = range_image.project(Sweep(sweep.stamp, sweep.points.astype(np.float64), sweep.point_time.astype(np.float64),
                                     sweep.ring, sweep.column, height=sweep.height, width=sweep.width),
                               cfg.sensor, cfg.features)
    for a, b in ((image.points, as64.points), (image.ring, as64.ring), (image.range_m, as64.range_m)):
        _same(a, b)
    labels = features.feature_labels(image, None, cfg.features)
    assert labels.dtype == np.int8
    assert (labels == 1).sum() > 0
    feats = features.extract_features(image, image.points, cfg.features)
    assert len(feats.surfs) > 0
    assert feats.surfs.flags.writeable


SCRIPT = textwrap.dedent("""
    import importlib.abc, json, sys
    HIDDEN = {hidden!r}

    class Hide(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name in HIDDEN:
                raise ModuleNotFoundError(f"No module named {{name!r}} (not built)", name=name)
            return None

    sys.meta_path.insert(0, Hide())
    from mrnc_eval.cli import main
    print(json.dumps({{"code": main(sys.argv[1:])}}))
""")


def _cli(hidden: tuple[str, ...], argv: list[str], cwd: Path) -> tuple[int, str]:
    env = {"PYTHONPATH": str(REPO), "HOME": str(cwd), "PATH": "/usr/bin:/bin"}
    proc = subprocess.run([sys.executable, "-c", SCRIPT.format(hidden=hidden), *argv], cwd=cwd, capture_output=True,
                          text=True, timeout=300, env=env, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return int(proc.stdout.strip().splitlines()[-1].split(":")[1].strip(" }")), proc.stderr


def test_slam_without_the_built_kernels_stops_at_once_and_says_how_to_build_them(tmp_path: Path) -> None:
    log = str(REPO / "sample_logs" / "loop_forest.bag")
    code, err = _cli(("mrnc_eval.slam._prep_kernels",), ["slam", log, "--out", str(tmp_path / "out")], tmp_path)
    assert code == 2
    assert "mrnc_eval.slam._prep_kernels" in err
    assert "gcc" in err
    assert "python3-dev" in err
    assert "reinstall" in err
    assert not (tmp_path / "out").exists()  # stopped before any work
    # negative control: the same check with nothing hidden lets the verb past it (--dump-config: no run)
    code, err = _cli((), ["slam", log, "--dump-config"], tmp_path)
    assert code == 0, err


def test_the_prep_side_of_a_slam_run_imports_no_numba() -> None:
    """What the reader thread and the per-sweep stages import (range image, deskew, features, the
    gyro track, sweep preparation) loads no numba nor llvmlite (scan_to_map.py's own kernels are a
    separate change)."""
    code = ("import sys; import mrnc_eval.slam.sweep_prep, mrnc_eval.slam.deskew, mrnc_eval.slam.imu, "
            "mrnc_eval.slam.features, mrnc_eval.slam.range_image; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('numba', 'llvmlite')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True,
                         env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})
    assert out.stdout.strip() == "[]"
    control = subprocess.run([sys.executable, "-c", code.replace("mrnc_eval.slam.range_image;",
                                                                 "mrnc_eval.slam.range_image, numba;")],
                             capture_output=True, text=True, timeout=120, check=True,
                             env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})
    assert "numba" in control.stdout  # the check sees numba when it is imported
