"""CLI glue (rpe options, KITTI pairing, output files), KITTI drift against a literal devkit-style
loop, Table I from a YAML manifest, hostile names in rendered tables."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.cli import main
from mrnc_eval.data import Trajectory
from mrnc_eval.errors import InputError
from mrnc_eval.evaluation.drift import drift, kitti_drift
from mrnc_eval.geometry import lie
from mrnc_eval.io.trajectory_files import read_trajectory, write_tum
from mrnc_eval.reports.tables import render_table
from tests.evaluation.evo_reference import make_pair


def _devkit_drift(gt: np.ndarray, est: np.ndarray, lengths, step: int = 10):
    """The KITTI odometry devkit's loop, written out per segment with general 4x4 inverses."""
    dist = [0.0]
    for k in range(1, len(gt)):
        dist.append(dist[-1] + float(np.linalg.norm(gt[k, :3, 3] - gt[k - 1, :3, 3])))
    out = {}
    for L in lengths:
        t_err, r_err = [], []
        for first in range(0, len(gt), step):
            last = next((k for k in range(first, len(gt)) if dist[k] > dist[first] + L), None)
            if last is None:
                continue
            dg = np.linalg.inv(gt[first]) @ gt[last]
            de = np.linalg.inv(est[first]) @ est[last]
            e = np.linalg.inv(de) @ dg
            cos = np.clip((np.trace(e[:3, :3]) - 1) / 2, -1, 1)
            t_err.append(np.linalg.norm(e[:3, 3]) / L)
            r_err.append(np.degrees(np.arccos(cos)) / L)
        if t_err:
            out[L] = (100 * np.mean(t_err), np.mean(r_err))
    return out


def test_drift_equals_a_devkit_style_loop() -> None:
    ref, est = make_pair(n=1500, seed=6)
    est = Trajectory(ref.stamps, est.positions, est.quat_xyzw, name="est")  # index-aligned
    lengths = (5.0, 10.0, 20.0)
    ours = kitti_drift(lie.poses(ref), lie.poses(est), lengths=lengths)
    theirs = _devkit_drift(lie.poses(ref), lie.poses(est), lengths)
    assert set(ours.trans_pct) == set(theirs)
    for L, (t, r) in theirs.items():
        assert ours.trans_pct[L] == pytest.approx(t, rel=1e-9)
        assert ours.rot_deg_per_m[L] == pytest.approx(r, rel=1e-6)  # devkit's arccos loses digits
    # drift is invariant to a rigid alignment of the estimate, not to a scale
    assert drift(ref, est, align="se3", by_index=True, lengths=lengths).trans_pct[5.0] == pytest.approx(
        ours.trans_pct[5.0], rel=1e-9)


def _kitti_file(path: Path, poses: np.ndarray) -> Path:
    np.savetxt(path, poses[:, :3, :].reshape(-1, 12), fmt="%.12e")
    return path


def test_kitti_broken_rotation_names_the_line(tmp_path: Path) -> None:
    ref, _ = make_pair(n=20)
    t = lie.poses(ref)
    t[7, 0, 0] += 1e-3
    p = _kitti_file(tmp_path / "poses.txt", t)
    text = p.read_text().splitlines()
    p.write_text("# KITTI poses\n" + "\n".join(text) + "\n")
    with pytest.raises(InputError, match=r"poses\.txt.*line 9: the 3x3 block is not a rotation"):
        read_trajectory(p)


def test_kitti_pairs_by_index_and_refuses_mixed_formats(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ref, est = make_pair(n=300, seed=2)
    k_ref = _kitti_file(tmp_path / "ref.txt", lie.poses(ref))
    k_est = _kitti_file(tmp_path / "est.txt", lie.poses(est))
    assert main(["ape", str(k_ref), str(k_est), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)["results"]
    assert out[0]["stats"]["n"] == 300
    write_tum(tmp_path / "est.tum", est)
    assert main(["ape", str(k_ref), str(tmp_path / "est.tum")]) == 2
    assert "KITTI" in capsys.readouterr().err


def test_rpe_cli_drift_pairs_from_reference_and_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ref, est = make_pair(n=3000, seed=3)
    write_tum(tmp_path / "gt.tum", ref)
    write_tum(tmp_path / "est.tum", est)
    args = ["rpe", str(tmp_path / "gt.tum"), str(tmp_path / "est.tum"), "--delta", "1", "--delta-unit", "m",
            "--align", "sim3", "--json"]
    assert main(args) == 0
    from_est = json.loads(capsys.readouterr().out)["results"][0]
    assert main(args + ["--pairs-from-reference", "--drift", "--table", str(tmp_path / "r.html"),
                        "--plot", str(tmp_path / "r.svg")]) == 0
    from_ref = json.loads(capsys.readouterr().out)["results"][0]
    assert from_ref["stats"]["n"] < from_est["stats"]["n"]  # the noisy estimate travels farther: more 1 m pairs
    assert from_ref["drift"]["lengths_m"][-1] < 100
    assert from_ref["drift"]["n_segments"] > 0
    assert "pairs from the reference" in (tmp_path / "r.html").read_text()
    assert (tmp_path / "r.svg").read_text().lstrip().startswith("<?xml")
    assert main(args[:-1] + ["--plot", str(tmp_path / "r.txt")]) == 2
    assert not (tmp_path / "r.txt").exists()


def test_table_from_yaml_manifest_with_missing_and_hostile_names(tmp_path: Path) -> None:
    ref, est = make_pair(n=800, seed=1)
    write_tum(tmp_path / "gt.tum", ref)
    write_tum(tmp_path / "a.tum", est)
    (tmp_path / "m.yaml").write_text(
        "sequences:\n"
        "  '<seq & 1>':\n"
        "    reference: gt.tum\n"
        "    methods: {'<b>LIO</b>': a.tum, gone: missing.tum, none: null}\n"
        "  seq2:\n"
        "    reference: gt.tum\n"
        "    methods: {'<b>LIO</b>': a.tum}\n"
    )
    from mrnc_eval.commands.table import build_table_one

    table = build_table_one(tmp_path / "m.yaml")
    assert table.row_labels == ["<seq & 1>", "seq2", "Mean"]
    col = {m: k for k, m in enumerate(table.column_labels)}
    assert isinstance(table.cells[0][col["<b>LIO</b>"]], float)
    assert table.cells[0][col["gone"]] == "Failed"
    assert table.cells[1][col["none"]] == "not run"  # seq2 does not list the method: never run there (issue 26)
    assert table.cells[2][col["gone"]] == "Failed"  # no non-failed cell: the mean is Failed too
    html = render_table(table, "html")
    assert "<b>" not in html
    assert "&lt;b&gt;LIO&lt;/b&gt;" in html
    assert "&lt;seq &amp; 1&gt;" in html
    tex = render_table(table, "latex")
    assert r"\&" in tex
    assert "\\toprule" in tex
    assert "\\bottomrule" in tex
    assert main(["table", str(tmp_path / "m.yaml"), "--out", str(tmp_path / "t.md")]) == 0
    assert "Failed" in (tmp_path / "t.md").read_text()


@pytest.mark.parametrize(("fmt", "suffix"), [("mcap", ".mcap"), ("bag", ".bag")])
def test_log_topic_spec_reads_odometry_from_a_log(tmp_path: Path, fmt: str, suffix: str,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    from mrnc_eval.io.writers import LogWriter

    ref, est = make_pair(n=200, seed=5)
    log_path = tmp_path / f"run{suffix}"
    with LogWriter(log_path, fmt=fmt) as w:
        w.write_odometry("/ground_truth", ref, "map", "base_link")
        w.write_odometry("/odom_est", est, "map", "base_link")
    write_tum(tmp_path / "gt.tum", ref)
    got = read_trajectory(f"{log_path}:/ground_truth")
    np.testing.assert_allclose(got.stamps, ref.stamps, atol=1e-9)
    np.testing.assert_allclose(got.positions, ref.positions, atol=1e-12)
    assert main(["ape", str(tmp_path / "gt.tum"), f"{log_path}:/odom_est", f"{log_path}:/ground_truth", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)["results"]
    assert out[1]["stats"]["max"] < 1e-6
    assert out[0]["stats"]["rmse"] > 0.01
    assert main(["ape", str(tmp_path / "gt.tum"), f"{log_path}:/nope"]) != 0
    assert "/nope" in capsys.readouterr().err


def test_plot_decimation_keeps_the_peak() -> None:
    from mrnc_eval.commands.trajectory_eval import _decimated_max

    e = np.zeros(1_000_003)
    e[777_777] = 5.0
    t, d = _decimated_max(np.arange(e.size, dtype=float), e)
    assert d.size == 10000
    assert d.max() == 5.0
    assert t.size == d.size
