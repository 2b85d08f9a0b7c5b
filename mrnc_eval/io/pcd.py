"""Write a point cloud as PCD v0.7 (binary, float32 x y z: what open3d and PCL write for a bare
cloud), without open3d. Reading .pcd scans is io/scan_folder.py's job."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray


def write_pcd_xyz(path: Path, points: NDArray[np.floating]) -> None:
    """(N, 3) positions as an unorganised (HEIGHT 1) binary PCD with float32 x, y, z, identity viewpoint."""
    xyz = np.ascontiguousarray(points, dtype="<f4").reshape(-1, 3)
    header = ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
              f"COUNT 1 1 1\nWIDTH {len(xyz)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(xyz)}\nDATA binary\n")
    with open(path, "wb") as fh:
        fh.write(header.encode("ascii"))
        xyz.tofile(fh)
