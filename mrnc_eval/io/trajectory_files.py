"""Trajectory files: TUM, KITTI poses, EuRoC ground-truth CSV, and `log:/topic` specs.

Parsing is strict (like evo: TUM rows of exactly 8 numbers, KITTI of 12) but errors name
the file and the line (io.number_table: a fast path for plain files, a strict one for the rest).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mrnc_eval.data import Trajectory
from mrnc_eval.errors import InputError
from mrnc_eval.io.number_table import first_bad_line, read_columns
from mrnc_eval.io.trajectory_inputs import TrajectorySpec, parse_trajectory_spec, trajectory_file_in
from mrnc_eval.io.validate import bad_poses


def read_tum(path: str | Path) -> Trajectory:
    path = Path(path)
    cols = read_columns(path, 8)  # views into one block: no copies of 1e6-pose arrays
    return Trajectory(cols[0], cols[1:4].T, cols[4:8].T, name=path.stem)


def read_kitti(path: str | Path) -> Trajectory:
    """KITTI poses: 12 numbers (3x4, row-major) per line, no stamps (stamps = line index).
    Rotation blocks must be orthonormal with det +1 (within evo's SO(3) check's tolerances):
    a quaternion would silently hide a broken matrix. The matrices are kept as read
    (`Trajectory.rotations`): evaluation uses them unchanged, as evo does."""
    from mrnc_eval.geometry.lie import matrix_to_quat_xyzw

    path = Path(path)
    a = np.ascontiguousarray(read_columns(path, 12).T).reshape(-1, 3, 4)
    rot = a[:, :, :3]
    # evo's test (np.allclose, atol 1e-6, rtol 1e-5): files printed to 6 digits must pass
    gram = np.abs(np.matmul(np.swapaxes(rot, 1, 2), rot) - np.eye(3)) > 1e-6 + 1e-5 * np.eye(3)
    bad = gram.any(axis=(1, 2)) | (np.abs(np.linalg.det(rot) - 1.0) > 1e-6 + 1e-5)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InputError(path, f"line {_data_line_number(path, k)}: the 3x3 block is not a rotation "
                               f"(R^T R != I or det != 1 within 1e-6 + 1e-5 |I|); {int(bad.sum())} such pose(s)")
    return Trajectory(np.arange(a.shape[0], dtype=float), a[:, :, 3].copy(), matrix_to_quat_xyzw(rot),
                      name=path.stem, rotations=np.ascontiguousarray(rot))


def _data_line_number(path: Path, row: int) -> int:
    """1-based file line of data row `row` (comments and blank lines skipped)."""
    with path.open(encoding="utf-8-sig", errors="replace") as fh:
        k = -1
        for number, line in enumerate(fh, 1):
            if line.strip() and not line.startswith("#"):
                k += 1
                if k == row:
                    return number
    return row + 1


def read_euroc(path: str | Path) -> Trajectory:
    """EuRoC ground truth data.csv: ns, x, y, z, qw, qx, qy, qz, (velocities, biases...).
    Stamps are ns / 1e9 in float64 as evo (about 0.25 us resolution at today's epochs)."""
    import pandas as pd

    path = Path(path)
    try:
        df = pd.read_csv(path, comment="#", header=None, engine="c", dtype=np.float64, encoding="utf-8-sig")
    except FileNotFoundError as err:
        raise InputError(path, "no such file") from err
    except pd.errors.EmptyDataError as err:
        raise InputError(path, "no poses (the file is empty or only comments)") from err
    except (ValueError, pd.errors.ParserError) as err:
        raise InputError(path, f"not a EuRoC ground-truth CSV ({first_bad_line(path, -1, ',')})") from err
    a = df.to_numpy()
    if a.shape[1] < 8:
        raise InputError(path, f"EuRoC CSV needs at least 8 columns (ns, x, y, z, qw, qx, qy, qz), found {a.shape[1]}")
    if not np.isfinite(a[:, :8]).all():
        row = int(np.flatnonzero(~np.isfinite(a[:, :8]).all(axis=1))[0])
        raise InputError(path, f"line {_data_line_number(path, row)}: missing or non-finite value")
    name = path.parent.name if path.stem == "data" and path.parent.name else path.stem
    return Trajectory(np.divide(a[:, 0], 1e9), a[:, 1:4].copy(), a[:, [5, 6, 7, 4]].copy(), name=name)


def write_tum(path: str | Path, traj: Trajectory) -> None:
    """TUM text: stamp x y z qx qy qz qw (stamps to the nanosecond)."""
    data = np.column_stack([traj.stamps, traj.positions, traj.quat_xyzw])
    np.savetxt(path, data, fmt=["%.9f"] + ["%.9f"] * 3 + ["%.12f"] * 4, delimiter=" ")


def write_kitti(path: str | Path, traj: Trajectory) -> None:
    """KITTI poses: the 3x4 [R | t] of each pose, row-major, one line per pose (no stamps: pair
    them with the TUM file's lines)."""
    from mrnc_eval.geometry.lie import quat_xyzw_to_matrix

    rt = np.concatenate([quat_xyzw_to_matrix(traj.quat_xyzw), traj.positions[:, :, None]], axis=2)
    np.savetxt(path, rt.reshape(-1, 12), fmt="%.9f", delimiter=" ")


def read_trajectory(spec: str | Path | TrajectorySpec, *, fmt: str | None = None) -> Trajectory:
    """A trajectory from a file or a `log:/topic` spec; the format by suffix unless given."""
    parsed = parse_trajectory_spec(spec)
    if parsed.topic is not None:
        return _from_log(parsed.path, parsed.topic)
    path = trajectory_file_in(Path(parsed.path))  # a result folder gives its trajectory; a bare log names its topics
    kind = fmt or trajectory_format(path)
    readers = {"tum": read_tum, "kitti": read_kitti, "euroc": read_euroc}
    if kind not in readers:
        raise InputError(path, f"unknown trajectory format {kind!r} (tum, kitti, euroc)")
    traj = readers[kind](path)
    bad, what = bad_poses(traj.stamps, traj.positions, traj.quat_xyzw)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InputError(path, f"line {_data_line_number(path, k)}: {what}; {int(bad.sum())} such pose(s) of "
                         f"{len(traj)} (the same check logs get: io/validate.py)")
    return traj


def check_trajectory(traj: Trajectory) -> Trajectory:
    """A trajectory handed over as an object (the Python API) gets the check files and logs get."""
    bad, what = bad_poses(traj.stamps, traj.positions, traj.quat_xyzw)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InputError(f"trajectory {traj.name or '(unnamed)'!r}", f"pose {k}: {what}; {int(bad.sum())} such "
                         f"pose(s) of {len(traj)}")
    return traj


def is_kitti_file(spec: str | Path | TrajectorySpec) -> bool:
    """Whether `spec` names a KITTI pose file (no stamps: it pairs line by line)."""
    parsed = parse_trajectory_spec(spec)
    path = Path(parsed.path)
    return parsed.topic is None and path.is_file() and trajectory_format(path) == "kitti"


def _from_log(log: str, topic: str) -> Trajectory:
    from mrnc_eval.io import open_log

    with open_log(log) as lg:
        traj = lg.trajectory(topic)
    return Trajectory(traj.stamps, traj.positions, traj.quat_xyzw, name=f"{Path(log).name}:{topic}",
                      frame_id=traj.frame_id, child_frame_id=traj.child_frame_id)


def trajectory_format(path: Path) -> str:
    """tum, kitti or euroc: by suffix (.csv, .tum), else by the first data line (12 numbers: KITTI)."""
    with path.open(encoding="utf-8-sig", errors="replace") as fh:
        first = next((line for line in fh if line.strip() and not line.startswith("#")), None)
    if first is None:
        raise InputError(path, "file is empty")
    suffix = path.suffix.lower()
    if suffix in (".csv", ".tum"):
        return "euroc" if suffix == ".csv" else "tum"
    return "kitti" if len(first.split()) == 12 else "tum"
