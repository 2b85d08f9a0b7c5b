"""A folder of LiDAR scans as SLAM input (kiss-icp's generic loader habit): one `.bin` (KITTI
velodyne: float32 x, y, z, intensity) or `.pcd` (ASCII or binary; x, y, z and optional
intensity) file per sweep, in file-name order, with their stamps in `timestamps.txt` (or
KITTI's `times.txt`): one number of seconds per line, one line per scan. Points are in the
sensor frame; zero and non-finite points (no return) are dropped, as the log reader does."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.data import Sweep
from mrnc_eval.errors import InputError

SCAN_SUFFIXES = (".bin", ".pcd")
STAMP_FILES = ("timestamps.txt", "times.txt")
_PCD_TYPES = {("F", 4): "f4", ("F", 8): "f8", ("I", 1): "i1", ("I", 2): "i2", ("I", 4): "i4", ("U", 1): "u1",
              ("U", 2): "u2", ("U", 4): "u4"}


@dataclass(frozen=True)
class ScanFolder:
    """A folder of .bin/.pcd scans and their stamps."""

    path: Path
    files: tuple[Path, ...]
    stamps: NDArray[np.float64]

    @property
    def duration_s(self) -> float:
        return float(self.stamps[-1] - self.stamps[0]) if self.stamps.size else 0.0

    @property
    def max_gap_s(self) -> float:
        return float(np.max(np.diff(self.stamps))) if self.stamps.size > 1 else 0.0


def is_scan_folder(path: Path) -> bool:
    """A directory holding .bin or .pcd scans (a ROS 2 bag folder holds metadata.yaml instead)."""
    path = Path(path)
    return path.is_dir() and not (path / "metadata.yaml").exists() and any(
        p.suffix.lower() in SCAN_SUFFIXES for p in path.iterdir())


def open_scan_folder(path: Path) -> ScanFolder:
    """The scans and their stamps; InputError naming the folder or file and the problem."""
    path = Path(path)
    files = tuple(sorted(p for p in path.iterdir() if p.suffix.lower() in SCAN_SUFFIXES and p.is_file()))
    if not files:
        raise InputError(path, "no .bin or .pcd scans in the folder")
    stamp_file = next((path / n for n in STAMP_FILES if (path / n).is_file()), None)
    if stamp_file is None:
        raise InputError(path, f"no {' or '.join(STAMP_FILES)} beside the scans (one stamp in seconds per line, "
                         "one line per scan)")
    try:
        stamps = np.loadtxt(stamp_file, dtype=np.float64, ndmin=1, comments="#")
    except ValueError as err:
        raise InputError(stamp_file, f"not one number per line: {err}") from None
    if stamps.ndim != 1 or stamps.size != len(files):
        raise InputError(stamp_file, f"{stamps.size} stamps for {len(files)} scans; one per scan, in file-name order")
    if not np.all(np.isfinite(stamps)) or np.any(np.diff(stamps) <= 0):
        raise InputError(stamp_file, "stamps must be finite and increasing")
    return ScanFolder(path, files, stamps)


def _read_bin(path: Path) -> tuple[NDArray[np.float32], NDArray[np.float32] | None]:
    raw = np.fromfile(path, dtype="<f4")
    if raw.size % 4:
        raise InputError(path, f"{raw.size * 4} bytes is not a whole number of KITTI points (16 bytes each)")
    pts = raw.reshape(-1, 4)
    return np.ascontiguousarray(pts[:, :3]), np.ascontiguousarray(pts[:, 3])


def _pcd_header(path: Path, fh: BinaryIO) -> dict[str, list[str]]:
    header: dict[str, list[str]] = {}
    for _ in range(64):
        line = fh.readline().decode("ascii", "replace").strip()
        if not line or line.startswith("#"):
            continue
        key, *values = line.split()
        header[key.upper()] = values
        if key.upper() == "DATA":
            return header
    raise InputError(path, "PCD header without a DATA line")


def _read_pcd(path: Path) -> tuple[NDArray[np.float32], NDArray[np.float32] | None]:
    with open(path, "rb") as fh:
        h = _pcd_header(path, fh)
        names = h.get("FIELDS", [])
        if not {"x", "y", "z"} <= set(names):
            raise InputError(path, "PCD without x, y, z fields")
        sizes, types = [int(v) for v in h.get("SIZE", [])], h.get("TYPE", [])
        counts = [int(v) for v in h.get("COUNT", ["1"] * len(names))]
        n = int(h.get("POINTS", ["0"])[0])
        kind = h["DATA"][0].lower()
        if kind == "ascii":
            table = np.loadtxt(fh, dtype=np.float64, ndmin=2, max_rows=n)
            cols = {name: int(sum(counts[:k])) for k, name in enumerate(names)}
            xyz = table[:, [cols["x"], cols["y"], cols["z"]]].astype(np.float32)
            inten = table[:, cols["intensity"]].astype(np.float32) if "intensity" in cols else None
            return xyz, inten
        if kind != "binary":
            raise InputError(path, f"PCD DATA {kind} is not supported (ascii or binary)")
        try:
            fields: list[tuple[str, str] | tuple[str, str, tuple[int]]] = [
                (name, "<" + _PCD_TYPES[(t, s)]) if c == 1 else (name, "<" + _PCD_TYPES[(t, s)], (c,))
                for name, s, t, c in zip(names, sizes, types, counts, strict=True)]
            dtype = np.dtype(fields)
        except (KeyError, ValueError) as err:
            raise InputError(path, f"PCD field types not understood: {err}") from None
        data = np.fromfile(fh, dtype=dtype, count=n)
    if data.shape[0] != n:
        raise InputError(path, f"PCD body has {data.shape[0]} of {n} points (truncated)")
    xyz = np.column_stack([data[a].astype(np.float32) for a in "xyz"])
    inten = data["intensity"].astype(np.float32) if "intensity" in names else None
    return xyz, inten


def scan_sweeps(folder: ScanFolder) -> Iterator[Sweep]:
    """One Sweep per file, no-return points (zero or non-finite) dropped."""
    for path, stamp in zip(folder.files, folder.stamps, strict=True):
        xyz, inten = _read_bin(path) if path.suffix.lower() == ".bin" else _read_pcd(path)
        keep = np.all(np.isfinite(xyz), axis=1) & np.any(xyz != 0, axis=1)
        yield Sweep(stamp=float(stamp), points=np.ascontiguousarray(xyz[keep]),
                    intensity=None if inten is None else inten[keep], frame_id="")
