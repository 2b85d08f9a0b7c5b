"""kiss-icp's and notebook users' habits: `slam --topic`, a time window or `--n-scans` on a log,
and DataFrames with seconds_from_start, distance_from_start_m and an optional time index."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.cli import main
from mrnc_eval.io import open_log
from mrnc_eval.io.trajectory_files import read_tum
from tests.export.conftest import Runs
from tests.needs import need_module


def _run(args: list[str], out: Path) -> Path:
    assert main(["slam", *args, "--out", str(out)]) in (0, 1)  # 1: a gate on the tiny log
    (run,) = [p for p in out.iterdir() if p.is_dir() and not p.is_symlink()]
    return run


def test_slam_topic_window_and_n_scans(sim_runs: Runs, tmp_path: Path) -> None:
    need_module("kiss_icp", "kiss-icp is not installed (pip install 'mrnc-eval[kiss-icp]')")
    log = str(sim_runs.log)
    with open_log(sim_runs.log) as lg:
        t0 = lg.start_s
        lidar = lg.roles["lidar"]
    base = ["--method", "kiss-icp", "--topic", lidar]
    n10 = read_tum(_run([log, *base, "--n-scans", "10"], tmp_path / "n") / "trajectory.tum")
    assert len(n10) == 10
    win = _run([log, *base, "--start", "2", "--end", "4.5"], tmp_path / "w")
    traj = read_tum(win / "trajectory.tum")
    rel = traj.stamps - t0
    assert rel.min() >= 2.0
    assert rel.max() <= 4.5
    assert len(traj) >= 10  # the sweeps of 2.5 s at 5 Hz (record_every 2 of 10 Hz): 12 or 13
    result = json.loads((win / "result.json").read_text())
    assert result["extra"]["window"] == {"start_s": 2.0, "end_s": 4.5, "n_scans": None}
    whole = read_tum(sim_runs.slam / "trajectory.tum")
    assert len(whole) > len(traj)  # the window cut something (the control: the whole log's run)
    # a topic the log does not have is an error naming it, and writes no run
    assert main(["slam", log, "--method", "kiss-icp", "--topic", "/nope", "--out", str(tmp_path / "bad")]) == 4
    assert not any((tmp_path / "bad").glob("*/result.json"))
    assert main(["slam", log, "--end", "0", "--out", str(tmp_path / "bad")]) == 2


def test_dataframes_have_seconds_distance_and_a_time_index(tmp_path: Path) -> None:
    from mrnc_eval import api
    from tests.evaluation.evo_reference import make_pair

    ref, est = make_pair(n=500, seed=2)
    r = api.ape(ref, est, align="se3")
    df = r.to_dataframe()
    assert {"t_s", "seconds_from_start", "distance_from_start_m", "error_m"} <= set(df.columns)
    assert df["seconds_from_start"].iloc[0] == 0.0
    np.testing.assert_allclose(df["seconds_from_start"], df["t_s"] - df["t_s"].iloc[0])
    steps = np.linalg.norm(np.diff(r.ref_xyz, axis=0), axis=1)
    assert df["distance_from_start_m"].iloc[-1] == pytest.approx(steps.sum())
    assert np.all(np.diff(df["distance_from_start_m"]) >= 0)
    indexed = r.to_dataframe(time_index=True)
    assert indexed.index.name == "time_s"
    t_mid = float(df["t_s"].iloc[250])
    assert indexed.loc[t_mid:, "error_m"].size == 250  # slicing by time works
    assert df.attrs["alignment"]["mode"] == "se3"
    p = api.rpe(ref, est, delta=1.0, delta_unit="m", pairs_from="reference")
    pdf = p.to_dataframe(time_index=True)
    assert {"seconds_from_start", "distance_from_start_m"} <= set(pdf.columns)
    gaps = np.diff(pdf["distance_from_start_m"])  # consecutive pairs: 1 m and a step's overshoot apart
    assert np.all(gaps >= 1.0)
    assert np.all(gaps < 1.2)


def _write_pcd(path: Path, xyz: np.ndarray, inten: np.ndarray, binary: bool) -> None:
    head = ("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
            f"WIDTH {len(xyz)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(xyz)}\n"
            f"DATA {'binary' if binary else 'ascii'}\n")
    table = np.column_stack([xyz, inten]).astype("<f4")
    with path.open("wb") as fh:
        fh.write(head.encode())
        if binary:
            fh.write(table.tobytes())
        else:
            np.savetxt(fh, table, fmt="%.9g")


def test_slam_on_a_folder_of_bin_and_pcd_scans(sim_runs: Runs, tmp_path: Path) -> None:
    """The log's sweeps written as KITTI .bin and PCD (binary, ASCII) files with timestamps.txt:
    `slam FOLDER --method kiss-icp` reads them back exactly and tracks the ground truth."""
    need_module("kiss_icp", "kiss-icp is not installed (pip install 'mrnc-eval[kiss-icp]')")
    from mrnc_eval.io.scan_folder import open_scan_folder, scan_sweeps

    folder = tmp_path / "scans"
    folder.mkdir()
    with open_log(sim_runs.log) as lg:
        sweeps = list(lg.sweeps())
        gt = lg.ground_truth()
    stamps = []
    for k, s in enumerate(sweeps):
        inten = s.intensity if s.intensity is not None else np.zeros(len(s.points), np.float32)
        if k % 3 == 0:
            _write_pcd(folder / f"{k:06d}.pcd", s.points, inten, binary=k % 2 == 0)
        else:
            np.column_stack([s.points, inten]).astype("<f4").tofile(folder / f"{k:06d}.bin")
        stamps.append(f"{s.stamp:.9f}")
    (folder / "timestamps.txt").write_text("\n".join(stamps) + "\n")
    from mrnc_eval.io.trajectory_files import write_tum

    write_tum(folder / "ground_truth.tum", gt)
    back = list(scan_sweeps(open_scan_folder(folder)))
    assert len(back) == len(sweeps)
    for a, b in zip(back, sweeps, strict=True):
        np.testing.assert_allclose(a.points, b.points, rtol=0, atol=1e-6)  # ASCII %.9g: float32 round trip
        assert abs(a.stamp - b.stamp) < 1e-6
    run = _run([str(folder), "--method", "kiss-icp"], tmp_path / "out")
    traj = read_tum(run / "trajectory.tum")
    assert len(traj) == len(sweeps)
    result = json.loads((run / "result.json").read_text())
    ape = next(m["value"] for m in result["metrics"] if m["name"] == "ape_rmse_m")
    assert ape < 0.3  # the sensor's path against the base's ground truth (lever arm inside), kiss-icp on 6 s
    assert not any("mount_rpy_correction_deg" in w for w in result["warnings"])
    # a mount correction (from a config shared with the machine's logs) has nothing to turn here: said, not silent
    corrected = _run([str(folder), "--method", "kiss-icp", "--n-scans", "5", "--set",
                      "slam.sensor.mount_rpy_correction_deg=[0,1,0]"], tmp_path / "corrected")
    warnings = json.loads((corrected / "result.json").read_text())["warnings"]
    assert any("mount_rpy_correction_deg [0.0, 1.0, 0.0] ignored: a scan folder" in w for w in warnings)
    # lio needs an IMU: refused with the reason; a stamps file of the wrong length names itself
    assert main(["slam", str(folder), "--method", "lio", "--out", str(tmp_path / "lio")]) == 2
    (folder / "timestamps.txt").write_text("\n".join(stamps[:-1]) + "\n")
    assert main(["slam", str(folder), "--method", "kiss-icp", "--out", str(tmp_path / "short")]) == 4
