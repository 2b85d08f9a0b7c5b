"""The SLAM map's PLY and PCD writers (io/ply.py, io/pcd.py) without open3d: open3d reads back the
values we wrote, and our files hold the same bytes as the ones open3d wrote before (header comment
aside)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.io.pcd import write_pcd_xyz
from mrnc_eval.io.ply import read_ply_xyz, write_ply_xyz
from mrnc_eval.io.scan_folder import _read_pcd


def _map(n: int = 5000) -> np.ndarray:
    rng = np.random.default_rng(7)
    return rng.uniform(-200, 200, (n, 3)) + rng.normal(0, 1e-7, (n, 3))  # digits beyond float32


def _body(path: Path) -> bytes:
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n") if path.suffix == ".ply" else \
        data.index(b"DATA binary\n") + len(b"DATA binary\n")
    return data[end:]


def test_ply_and_pcd_read_back_by_open3d_and_by_us(tmp_path: Path) -> None:
    o3d = pytest.importorskip("open3d")  # the slam extra installs it (for the simulator)
    points = _map()
    write_ply_xyz(tmp_path / "map.ply", points)
    write_pcd_xyz(tmp_path / "map.pcd", points)
    ply = np.asarray(o3d.io.read_point_cloud(str(tmp_path / "map.ply")).points)
    pcd = np.asarray(o3d.io.read_point_cloud(str(tmp_path / "map.pcd")).points)
    np.testing.assert_array_equal(ply, points)  # PLY: double, every bit
    np.testing.assert_array_equal(pcd, points.astype(np.float32).astype(np.float64))  # PCD: float32
    assert not np.array_equal(pcd, points)  # (the PCD does round: the two checks above are not the same)
    np.testing.assert_array_equal(read_ply_xyz(tmp_path / "map.ply"), points)
    np.testing.assert_array_equal(_read_pcd(tmp_path / "map.pcd")[0], points.astype(np.float32))


def test_same_bytes_as_open3d_wrote(tmp_path: Path) -> None:
    o3d = pytest.importorskip("open3d")
    points = _map(300)
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    for name in ("o3d.ply", "o3d.pcd"):
        o3d.io.write_point_cloud(str(tmp_path / name), pc)
    write_ply_xyz(tmp_path / "ours.ply", points)
    write_pcd_xyz(tmp_path / "ours.pcd", points)
    assert _body(tmp_path / "ours.ply") == _body(tmp_path / "o3d.ply")
    assert _body(tmp_path / "ours.pcd") == _body(tmp_path / "o3d.pcd")
    assert (tmp_path / "ours.pcd").read_bytes() == (tmp_path / "o3d.pcd").read_bytes()  # same header too


def test_empty_cloud_is_a_valid_file(tmp_path: Path) -> None:
    write_ply_xyz(tmp_path / "e.ply", np.zeros((0, 3)))
    write_pcd_xyz(tmp_path / "e.pcd", np.zeros((0, 3)))
    assert read_ply_xyz(tmp_path / "e.ply").shape == (0, 3)
    assert _read_pcd(tmp_path / "e.pcd")[0].shape == (0, 3)
